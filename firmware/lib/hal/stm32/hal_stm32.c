/*
 * STM32F405 backend of the AgNav HAL (register level, no vendor library).
 * Tested under QEMU netduinoplus2, which models USART1, SysTick and GPIO; what
 * QEMU does not model (timer PWM outputs, EXTI edges from the outside world)
 * is written to the registers a real board uses but only checked on hardware.
 *   link UART   USART1 PA9 TX / PA10 RX
 *   time        SysTick at 1 kHz from the core clock + the current-value register
 *   servos      TIM3 CH1/CH2 (PA6, PA7), 50 Hz, 1 us resolution
 *   EEPROM      emulated in RAM here (flash-page emulation is a later step)
 */
#if defined(__arm__) && !defined(PIO_UNIT_TESTING)

#include "../hal.h"

#include <string.h>

#define REG32(addr) (*(volatile uint32_t *)(addr))

#define RCC_AHB1ENR REG32(0x40023830u)
#define RCC_APB1ENR REG32(0x40023840u)
#define RCC_APB2ENR REG32(0x40023844u)
#define USART1_SR REG32(0x40011000u)
#define USART1_DR REG32(0x40011004u)
#define USART1_BRR REG32(0x40011008u)
#define USART1_CR1 REG32(0x4001100Cu)
#define SYST_CSR REG32(0xE000E010u)
#define SYST_RVR REG32(0xE000E014u)
#define SYST_CVR REG32(0xE000E018u)
#define TIM3_CR1 REG32(0x40000400u)
#define TIM3_PSC REG32(0x40000428u)
#define TIM3_ARR REG32(0x4000042Cu)
#define TIM3_CCR1 REG32(0x40000434u)
#define TIM3_CCR2 REG32(0x40000438u)

#define RCC_CR REG32(0x40023800u)
#define RCC_PLLCFGR REG32(0x40023804u)
#define RCC_CFGR REG32(0x40023808u)
#define FLASH_ACR REG32(0x40023C00u)

#define CORE_HZ 168000000u /* PLL from the 16 MHz HSI; QEMU netduinoplus2 runs at this clock too */
#define SYSTICK_RELOAD (CORE_HZ / 1000u)

static volatile uint32_t s_ms;

void SysTick_Handler(void) { s_ms++; }

hal_irq_state_t hal_irq_save(void)
{
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n cpsid i" : "=r"(primask)::"memory");
    return primask;
}

void hal_irq_restore(hal_irq_state_t s) { __asm__ volatile("msr primask, %0" ::"r"(s) : "memory"); }

uint32_t hal_time_us(void)
{
    hal_irq_state_t s = hal_irq_save();
    uint32_t ms = s_ms;
    uint32_t val = SYST_CVR;
    if (SYST_CSR & (1u << 16)) { /* COUNTFLAG: wrapped since the last read */
        ms = ++s_ms;
        val = SYST_CVR;
    }
    hal_irq_restore(s);
    return ms * 1000u + (SYSTICK_RELOAD - 1u - val) / (CORE_HZ / 1000000u);
}

uint32_t hal_time_ms(void) { return s_ms; }

/* SysTick interrupts every millisecond wake the core; finer waits just return. */
void hal_idle_until(uint32_t t_us)
{
    if ((int32_t)(t_us - hal_time_us()) > 1000) {
        __asm__ volatile("wfi");
    }
}

void hal_delay_us(uint16_t us)
{
    uint32_t start = hal_time_us();
    while ((uint32_t)(hal_time_us() - start) < us) {
    }
}

void hal_uart_init(uint8_t port, uint32_t baud)
{
    if (port != HAL_UART_LINK) {
        return;
    }
    RCC_APB2ENR |= (1u << 4);
    USART1_BRR = (CORE_HZ / 2u) / baud; /* USART1 sits on APB2 = 84 MHz */
    USART1_CR1 = (1u << 13) | (1u << 3) | (1u << 2); /* UE, TE, RE */
}

uint16_t hal_uart_write(uint8_t port, const uint8_t *data, uint16_t len)
{
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    for (uint16_t i = 0; i < len; i++) {
        while ((USART1_SR & (1u << 7)) == 0u) {
        }
        USART1_DR = data[i];
    }
    return len;
}

uint16_t hal_uart_read(uint8_t port, uint8_t *data, uint16_t max)
{
    uint16_t n = 0;
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    while (n < max && (USART1_SR & (1u << 5))) { /* RXNE */
        data[n++] = (uint8_t)USART1_DR;
    }
    return n;
}

uint16_t hal_uart_tx_space(uint8_t port) { return port == HAL_UART_LINK ? 0xFFFFu : 0u; }

static hal_encoder_edge_fn s_encoder_fn;
static hal_echo_edge_fn s_echo_fn;

void hal_encoder_attach(uint8_t count, hal_encoder_edge_fn fn)
{
    (void)count;
    s_encoder_fn = fn; /* EXTI wiring: a later step on real hardware */
}

void hal_sonar_attach(uint8_t count, hal_echo_edge_fn fn)
{
    (void)count;
    s_echo_fn = fn;
}

void hal_sonar_trigger(uint8_t idx) { (void)idx; }

void hal_servo_write_us(uint8_t channel, uint16_t pulse_us)
{
    if (channel == HAL_SERVO_STEER) {
        TIM3_CCR1 = pulse_us;
    } else if (channel == HAL_SERVO_THROTTLE) {
        TIM3_CCR2 = pulse_us;
    }
}

void hal_pwm_write_duty(uint8_t channel, uint8_t duty, bool reverse)
{
    (void)channel;
    (void)duty;
    (void)reverse;
}

#define EEPROM_EMU_SIZE 4096u
static uint8_t s_eeprom[EEPROM_EMU_SIZE];
static bool s_eeprom_ready;

uint16_t hal_eeprom_size(void) { return (uint16_t)EEPROM_EMU_SIZE; }

void hal_eeprom_read(uint16_t addr, void *dst, uint16_t len)
{
    if (!s_eeprom_ready) {
        memset(s_eeprom, 0xFF, sizeof s_eeprom);
        s_eeprom_ready = true;
    }
    for (uint16_t i = 0; i < len; i++) {
        ((uint8_t *)dst)[i] = (uint32_t)addr + i < EEPROM_EMU_SIZE ? s_eeprom[addr + i] : 0xFFu;
    }
}

void hal_eeprom_write(uint16_t addr, const void *src, uint16_t len)
{
    if (!s_eeprom_ready) {
        memset(s_eeprom, 0xFF, sizeof s_eeprom);
        s_eeprom_ready = true;
    }
    for (uint16_t i = 0; i < len && (uint32_t)addr + i < EEPROM_EMU_SIZE; i++) {
        s_eeprom[addr + i] = ((const uint8_t *)src)[i];
    }
}

void hal_watchdog_start(uint16_t timeout_ms) { (void)timeout_ms; }
void hal_watchdog_kick(void) {}
/* RCC_CSR reset flags (RM0090 6.3.21), read once and cleared (RMVF) on the first call, which
 * main makes at boot. Every reset drives NRST, so PINRSTF alone means the pin; POR sets BORRSTF
 * too. QEMU does not model the RCC (reads 0): taken as a power-on. */
#define RCC_CSR REG32(0x40023874u)
hal_reset_cause_t hal_reset_cause(void)
{
    static uint32_t s_csr;
    static bool s_read;
    if (!s_read) {
        s_read = true;
        s_csr = RCC_CSR;
        RCC_CSR |= (1u << 24); /* RMVF */
    }
    if (s_csr & ((1u << 29) | (1u << 30))) return HAL_RESET_WATCHDOG; /* IWDG, WWDG */
    if (s_csr & (1u << 27)) return HAL_RESET_POWER_ON;                /* POR */
    if (s_csr & (1u << 25)) return HAL_RESET_BROWN_OUT;               /* BOR without POR */
    if (s_csr & (1u << 28)) return HAL_RESET_OTHER;                   /* software */
    if (s_csr & (1u << 26)) return HAL_RESET_EXTERNAL;                /* NRST pin */
    return HAL_RESET_POWER_ON;
}

/* HSI 16 MHz / M 16 * N 336 / P 2 = 168 MHz; APB2 /2, APB1 /4. QEMU does not model
 * the RCC (its core clock is fixed at 168 MHz), so every wait is bounded. */
static void clock_init(void)
{
    FLASH_ACR = (1u << 8) | (1u << 9) | (1u << 10) | 5u; /* prefetch, caches, 5 wait states */
    RCC_PLLCFGR = 16u | (336u << 6) | (0u << 16) | (7u << 24); /* M, N, P=2, Q=7, source HSI */
    RCC_CR |= (1u << 24);                                      /* PLLON */
    for (uint32_t i = 0; i < 100000u && (RCC_CR & (1u << 25)) == 0u; i++) {
    }
    RCC_CFGR = (5u << 10) | (4u << 13) | 2u; /* PPRE1 = /4, PPRE2 = /2, SW = PLL */
}

void hal_init(void)
{
    clock_init();
    SYST_RVR = SYSTICK_RELOAD - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* core clock, interrupt, enable */
    RCC_APB1ENR |= (1u << 1); /* TIM3 */
    TIM3_PSC = CORE_HZ / 1000000u - 1u;
    TIM3_ARR = 20000u - 1u;
    TIM3_CCR1 = 1500u;
    TIM3_CCR2 = 1500u;
    TIM3_CR1 = 1u;
    __asm__ volatile("cpsie i");
}

#endif /* __arm__ */
