/*
 * STM32F405 backend of the AgNav HAL (register level after RM0090, no vendor library).
 * Pin map and the board (Olimex STM32-H405): board.h; wiring, flashing: docs/stm32.md.
 *   clock       HSE 8 MHz crystal -> PLL -> 168 MHz SYSCLK, APB1 42 MHz, APB2 84 MHz, 48 MHz for
 *               USB; HSI 16 MHz -> PLL -> the same clocks when the crystal does not start
 *               (hal_clock_from_crystal() tells which)
 *   link UART   USART1 PA9 TX / PA10 RX, interrupt-driven rings (RX 256 B, TX 512 B), BRR rounded
 *   time        SysTick at 1 kHz from the core clock + the current-value register
 *   servos      TIM9 CH1/CH2 (PA2, PA3), 50 Hz, 1 us resolution
 *   H-bridges   TIM10 CH1 (PB8), TIM11 CH1 (PB9), 20 kHz, 8-bit duty scaled to the period; DIR on GPIO
 *   encoders    quadrature: TIM2, TIM3, TIM4, TIM8 in encoder mode (x4, filtered inputs, no CPU per
 *               edge), folded into the encoder record by hal_encoder_poll(); Hall: EXTI on A
 *   sonars      GPIO trigger pulse (two pins each fire four sonars of one ring group); echoes on
 *               one EXTI line each, both edges
 *   watchdog    IWDG from the ~32 kHz LSI
 *   EEPROM      4 KB emulated in flash sectors 1 and 2 (lib/flash_eeprom; the linker script keeps
 *               code out of them), erase and program run from RAM
 *
 * Under QEMU netduinoplus2 (7.2) USART1, SysTick, NVIC, SYSCFG, EXTI's registers and TIM2..5
 * are modelled; GPIO, RCC, FLASH, IWDG and TIM1, TIM8..14 are "unimplemented" (reads 0, writes
 * ignored) and nothing drives an EXTI line from a pin. What that leaves untested is listed in
 * docs/stm32.md. Every wait on a flag is bounded, so unmodelled blocks never hang.
 *
 * Built for the firmware (not for unit-test builds, which link the sim backend) and, under
 * other names, by test/test_hal_stm32 (AGNAV_HAL_STM32_UNDER_TEST).
 */
#if defined(__arm__) && (!defined(PIO_UNIT_TESTING) || defined(AGNAV_HAL_STM32_UNDER_TEST))

#include "../hal.h"
#include "../../encoder/encoder_isr.h"
#include "board.h"
#include "flash_eeprom.h"
#include "../../units/units.h"

#include <string.h>

#define REG32(addr) (*(volatile uint32_t *)(addr))

/* Register blocks by base address (RM0090 2.3). test/test_hal_stm32 points RCC and GPIO at RAM
 * to read back what this file writes there (QEMU does not model either block). */
#ifndef HAL_STM32_RCC_BASE
#define HAL_STM32_RCC_BASE 0x40023800u
#endif
#ifndef HAL_STM32_GPIO_BASE
#define HAL_STM32_GPIO_BASE 0x40020000u
#endif

/* RCC (RM0090 7.3) */
#define RCC_CR REG32(HAL_STM32_RCC_BASE + 0x00u)
#define RCC_PLLCFGR REG32(HAL_STM32_RCC_BASE + 0x04u)
#define RCC_CFGR REG32(HAL_STM32_RCC_BASE + 0x08u)
#define RCC_AHB1ENR REG32(HAL_STM32_RCC_BASE + 0x30u)
#define RCC_APB1ENR REG32(HAL_STM32_RCC_BASE + 0x40u)
#define RCC_APB2ENR REG32(HAL_STM32_RCC_BASE + 0x44u)
#define RCC_CSR REG32(HAL_STM32_RCC_BASE + 0x74u)
#define RCC_CR_HSEON (1u << 16)
#define RCC_CR_HSERDY (1u << 17)
#define RCC_CR_CSSON (1u << 19)
#define RCC_CR_PLLON (1u << 24)
#define RCC_CR_PLLRDY (1u << 25)
#define RCC_PLLCFGR_FIELDS 0x0F437FFFu /* PLLQ, PLLSRC, PLLP, PLLN, PLLM; the rest is reserved */
#define RCC_PLLCFGR_PLLSRC_HSE (1u << 22)
#define RCC_CFGR_SW_PLL 2u
#define RCC_CFGR_SWS_MASK (3u << 2)
#define RCC_CFGR_SWS_PLL (2u << 2)
#define RCC_CFGR_PRESCALERS 0xFCF0u /* PPRE2, PPRE1, HPRE */
#define RCC_CFGR_PPRE1_DIV4 (5u << 10)
#define RCC_CFGR_PPRE2_DIV2 (4u << 13)
#define RCC_APB2ENR_USART1 (1u << 4)
#define RCC_APB2ENR_SYSCFG (1u << 14)
/* RCC_CSR reset flags (RM0090 7.3.21) */
#define RCC_CSR_RMVF (1u << 24)
#define RCC_CSR_BORRSTF (1u << 25)
#define RCC_CSR_PINRSTF (1u << 26)
#define RCC_CSR_PORRSTF (1u << 27)
#define RCC_CSR_SFTRSTF (1u << 28)
#define RCC_CSR_IWDGRSTF (1u << 29)
#define RCC_CSR_WWDGRSTF (1u << 30)
#define RCC_CSR_LPWRRSTF (1u << 31)

#define FLASH_ACR REG32(0x40023C00u)
#define FLASH_ACR_PRFTEN (1u << 8)
#define FLASH_ACR_ICEN (1u << 9)
#define FLASH_ACR_DCEN (1u << 10)

#define USART1_SR REG32(0x40011000u)
#define USART1_DR REG32(0x40011004u)
#define USART1_BRR REG32(0x40011008u)
#define USART1_CR1 REG32(0x4001100Cu)

#define SYST_CSR REG32(0xE000E010u)
#define SYST_RVR REG32(0xE000E014u)
#define SYST_CVR REG32(0xE000E018u)
#define SCB_ICSR REG32(0xE000ED04u)
#define NVIC_ISER(n) REG32(0xE000E100u + 4u * (n))

/* GPIOx at the GPIO base + 0x400 * x (RM0090 8.4) */
#define GPIO_REG(port, off) REG32(HAL_STM32_GPIO_BASE + 0x400u * (uint32_t)(port) + (off))
#define GPIO_MODER(p) GPIO_REG(p, 0x00u)
#define GPIO_OTYPER(p) GPIO_REG(p, 0x04u)
#define GPIO_PUPDR(p) GPIO_REG(p, 0x0Cu)
#define GPIO_IDR(p) GPIO_REG(p, 0x10u)
#define GPIO_ODR(p) GPIO_REG(p, 0x14u)
#define GPIO_BSRR(p) GPIO_REG(p, 0x18u)
#define GPIO_AFR(p, hi) GPIO_REG(p, 0x20u + 4u * (hi))

#define SYSCFG_EXTICR(n) REG32(0x40013808u + 4u * (n)) /* n = line / 4 */
#define EXTI_IMR REG32(0x40013C00u)
#define EXTI_RTSR REG32(0x40013C08u)
#define EXTI_FTSR REG32(0x40013C0Cu)
#define EXTI_SWIER REG32(0x40013C10u)
#define EXTI_PR REG32(0x40013C14u)

/* Timers (RM0090 17.4 TIM1/8, 18.4 TIM2..5, 19.4/19.5 TIM9..14: the same offsets) */
#define TIM_REG(base, off) REG32((base) + (off))
#define TIM_CR1 0x00u
#define TIM_SMCR 0x08u
#define TIM_EGR 0x14u
#define TIM_CCMR1 0x18u
#define TIM_CCER 0x20u
#define TIM_CNT 0x24u
#define TIM_PSC 0x28u
#define TIM_ARR 0x2Cu
#define TIM_CCR1 0x34u
#define TIM_CCR2 0x38u
#define TIM_CR1_CEN (1u << 0)
#define TIM_CR1_ARPE (1u << 7)
#define TIM_CR1_CKD(n) ((uint32_t)(n) << 8) /* t_DTS = 2^n t_CK_INT: the input filters' clock */
#define TIM_SMCR_SMS_ENCODER3 3u           /* counts on both TI1FP1 and TI2FP2 edges (x4) */
#define TIM_EGR_UG 1u

#define IWDG_KR REG32(0x40003000u)
#define IWDG_PR REG32(0x40003004u)
#define IWDG_RLR REG32(0x40003008u)
#define IWDG_SR REG32(0x4000300Cu)

/* ---- clock tree ------------------------------------------------------------
 * Either source feeds the PLL a 2 MHz reference (RM0090 7.3.2 PLLM: 1-2 MHz, 2 MHz recommended to
 * limit jitter): VCO 2 MHz x 168 = 336 MHz (100-432 MHz), /2 = 168 MHz SYSCLK (P), /7 = 48 MHz for
 * USB OTG FS, SDIO, RNG (Q). AHB /1, APB1 /4 = 42 MHz (max 42), APB2 /2 = 84 MHz (max 84); timers
 * on a divided APB run at twice its clock (RM0090 7.2, clock tree): 84 MHz on APB1, 168 on APB2. */
#define HSI_HZ 16000000u
#define PLL_REF_HZ 2000000u
#define PLL_M_HSE (BOARD_HSE_HZ / PLL_REF_HZ)
#define PLL_M_HSI (HSI_HZ / PLL_REF_HZ)
#define PLL_N 168u
#define PLL_P 2u
#define PLL_Q 7u
#define CORE_HZ (PLL_REF_HZ * PLL_N / PLL_P)
#define APB1_HZ (CORE_HZ / 4u)
#define APB2_HZ (CORE_HZ / 2u)
#define APB1_TIMER_HZ (2u * APB1_HZ)
#define APB2_TIMER_HZ (2u * APB2_HZ)
_Static_assert(BOARD_HSE_HZ % PLL_REF_HZ == 0u && PLL_M_HSE >= 2u && PLL_M_HSE <= 63u, "HSE / M = 2 MHz");
_Static_assert(CORE_HZ == 168000000u, "168 MHz SYSCLK");
_Static_assert(PLL_REF_HZ * PLL_N / PLL_Q == 48000000u, "48 MHz for USB OTG FS");
_Static_assert(APB1_HZ <= 42000000u && APB2_HZ <= 84000000u, "APB limits (DS8626)");
/* Flash wait states for 150 < HCLK <= 168 MHz at 2.7-3.6 V (RM0090 3.5.1, Table 10). The PWR
 * regulator is in scale 1 after reset (VOS = 1), which 168 MHz needs. */
#define FLASH_WAIT_STATES 5u
/* Bounded waits, in SysTick counts of the 16 MHz HSI the core runs on meanwhile: the crystal's
 * start-up is 2 ms typical (DS8626, HSE 4-26 MHz oscillator characteristics): 100 ms is the give-up;
 * PLL lock and the clock switch take well under a millisecond. */
#define HSE_START_TICKS (HSI_HZ / 10u)
#define PLL_LOCK_TICKS (HSI_HZ / 500u)
#define RCC_WAIT_POLLS_MAX 20000000u /* also bounded by polls, should SysTick not count */

#define SYSTICK_RELOAD (CORE_HZ / 1000u)
#define LSI_HZ 32000u

/* NVIC numbers of the EXTI vectors (RM0090 table 61) */
#define IRQ_EXTI0 6u /* EXTI1..4 follow: 7..10 */
#define IRQ_EXTI9_5 23u
#define IRQ_EXTI15_10 40u

#define GPIO_MODE_IN 0u
#define GPIO_MODE_OUT 1u
#define GPIO_MODE_AF 2u
#define GPIO_PULL_NONE 0u
#define GPIO_PULL_UP 1u
#define GPIO_PULL_DOWN 2u

static const uint8_t s_servo_pin[HAL_SERVO_MAX] = BOARD_SERVO_PINS;
static const uint8_t s_hbridge_pwm_pin[HAL_PWM_MAX] = BOARD_HBRIDGE_PWM_PINS;
static const uint32_t s_hbridge_timer[HAL_PWM_MAX] = BOARD_HBRIDGE_TIMERS;
static const uint8_t s_hbridge_dir_pin[HAL_PWM_MAX] = BOARD_HBRIDGE_DIR_PINS;
static const uint8_t s_trigger_pin[BOARD_SONAR_TRIGGER_COUNT] = BOARD_SONAR_TRIGGER_PINS;
static const uint8_t s_trigger_of[HAL_SONAR_MAX] = BOARD_SONAR_TRIGGER_OF;
static const uint8_t s_echo_pin[HAL_SONAR_MAX] = BOARD_SONAR_ECHO_PINS;
static const uint32_t s_enc_timer[HAL_ENCODER_MAX] = BOARD_ENCODER_TIMERS;
static const uint8_t s_enc_a_pin[HAL_ENCODER_MAX] = BOARD_ENCODER_A_PINS;
static const uint8_t s_enc_b_pin[HAL_ENCODER_MAX] = BOARD_ENCODER_B_PINS;
static const uint8_t s_enc_af[HAL_ENCODER_MAX] = BOARD_ENCODER_AF;

/* ---- clock -------------------------------------------------------------- */
static bool s_clock_from_hse;
static uint32_t s_pllcfgr; /* what clock_init() wrote to RCC_PLLCFGR */

/* Wait until (*reg & mask) == want, for at most `ticks` counts of SysTick on the core clock (used
 * as a stopwatch before hal_init() starts the 1 kHz tick). */
static bool wait_bits(volatile uint32_t *reg, uint32_t mask, uint32_t want, uint32_t ticks)
{
    SYST_CSR = 0u;
    SYST_RVR = 0xFFFFFFu;
    SYST_CVR = 0u;
    SYST_CSR = 5u; /* processor clock, enabled, no interrupt */
    uint32_t start = SYST_CVR;
    for (uint32_t n = 0; n < RCC_WAIT_POLLS_MAX; n++) {
        if ((*reg & mask) == want) {
            return true;
        }
        if (((start - SYST_CVR) & 0xFFFFFFu) >= ticks) {
            break;
        }
    }
    return (*reg & mask) == want;
}

/* RCC_PLLCFGR for a 2 MHz reference from the crystal or the HSI (reserved bits kept). */
static uint32_t pll_config(uint32_t old, bool hse)
{
    uint32_t f = (hse ? PLL_M_HSE : PLL_M_HSI) | (PLL_N << 6) | (((PLL_P / 2u) - 1u) << 16) | (PLL_Q << 24) |
                 (hse ? RCC_PLLCFGR_PLLSRC_HSE : 0u);
    return (old & ~RCC_PLLCFGR_FIELDS) | f;
}

/* Start the crystal and wait for it (bounded); then the PLL from it, or from the HSI when it did
 * not start. Flash wait states go up first (RM0090 3.5.1: before the faster clock). With the
 * crystal the clock security system is on (RM0090 7.2.7): a crystal that stops later switches the
 * core to the HSI and raises the NMI, whose handler waits for the watchdog reset; that boot then
 * takes the HSI path. The PLL's lock and the switch are waited for with bounds and not checked
 * further (QEMU reads the RCC as 0, and a PLL that does not lock is a silicon fault). */
static void clock_init(void)
{
    FLASH_ACR = FLASH_ACR_PRFTEN | FLASH_ACR_ICEN | FLASH_ACR_DCEN | FLASH_WAIT_STATES;
    RCC_CR |= RCC_CR_HSEON;
    bool hse = wait_bits(&RCC_CR, RCC_CR_HSERDY, RCC_CR_HSERDY, HSE_START_TICKS);
    if (!hse) {
        RCC_CR &= ~RCC_CR_HSEON;
    }
    RCC_CR &= ~RCC_CR_PLLON; /* PLLCFGR is written with the PLL off */
    uint32_t pll = pll_config(RCC_PLLCFGR, hse);
    RCC_PLLCFGR = pll;
    RCC_CR |= RCC_CR_PLLON;
    (void)wait_bits(&RCC_CR, RCC_CR_PLLRDY, RCC_CR_PLLRDY, PLL_LOCK_TICKS);
    RCC_CFGR = (RCC_CFGR & ~RCC_CFGR_PRESCALERS) | RCC_CFGR_PPRE1_DIV4 | RCC_CFGR_PPRE2_DIV2; /* HPRE /1 */
    RCC_CFGR = (RCC_CFGR & ~3u) | RCC_CFGR_SW_PLL;
    (void)wait_bits(&RCC_CFGR, RCC_CFGR_SWS_MASK, RCC_CFGR_SWS_PLL, PLL_LOCK_TICKS);
    if (hse) {
        RCC_CR |= RCC_CR_CSSON;
    }
    s_clock_from_hse = hse;
    s_pllcfgr = pll;
}

bool hal_clock_from_crystal(void) { return s_clock_from_hse; }

/* ---- time --------------------------------------------------------------- */
static volatile uint32_t s_ms;

/* Reading CSR clears COUNTFLAG, so hal_time_us() only sees wraps this has not counted yet. */
void SysTick_Handler(void)
{
    (void)SYST_CSR;
    s_ms++;
}

hal_irq_state_t hal_irq_save(void)
{
    uint32_t primask;
    __asm__ volatile("mrs %0, primask\n cpsid i" : "=r"(primask)::"memory");
    return primask;
}

void hal_irq_restore(hal_irq_state_t s) { __asm__ volatile("msr primask, %0" ::"r"(s) : "memory"); }

/* With interrupts masked s_ms cannot move. A wrap the handler has not counted yet (it is
 * pending: interrupts were masked, or we run in an interrupt at or above its priority) shows
 * as COUNTFLAG or, if an earlier call already read that, as PENDSTSET; it is added here, not
 * to s_ms, since the handler still runs and counts it once. */
uint32_t hal_time_us(void)
{
    hal_irq_state_t s = hal_irq_save();
    uint32_t ms = s_ms;
    uint32_t val = SYST_CVR;
    bool wrapped = (SYST_CSR & (1u << 16)) != 0u; /* COUNTFLAG, cleared by this read */
    if (wrapped || (SCB_ICSR & (1u << 26)) != 0u) { /* PENDSTSET */
        ms++;
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

/* At least us microseconds: whole-microsecond readings, so one more than us must pass. */
void hal_delay_us(uint16_t us)
{
    uint32_t start = hal_time_us();
    while ((uint32_t)(hal_time_us() - start) <= us) {
    }
}

/* ---- GPIO --------------------------------------------------------------- */
static void gpio_config(uint8_t pin, uint32_t mode, uint32_t pull, uint32_t af)
{
    uint8_t port = BOARD_PIN_PORT(pin);
    uint32_t n = BOARD_PIN_NUM(pin);
    GPIO_MODER(port) = (GPIO_MODER(port) & ~(3u << (2u * n))) | (mode << (2u * n));
    GPIO_OTYPER(port) &= ~(1u << n); /* push-pull */
    GPIO_PUPDR(port) = (GPIO_PUPDR(port) & ~(3u << (2u * n))) | (pull << (2u * n));
    if (mode == GPIO_MODE_AF) {
        uint32_t shift = 4u * (n & 7u);
        GPIO_AFR(port, n >> 3) = (GPIO_AFR(port, n >> 3) & ~(0xFu << shift)) | (af << shift);
    }
}

/* BSRR: one store, no read-modify-write, safe against interrupts touching the same port. */
static void gpio_write(uint8_t pin, bool high)
{
    uint32_t n = BOARD_PIN_NUM(pin);
    GPIO_BSRR(BOARD_PIN_PORT(pin)) = high ? (1u << n) : (1u << (n + 16u));
}

static void gpio_clocks_on(void)
{
    RCC_AHB1ENR |= (1u << BOARD_PORT_COUNT) - 1u; /* GPIOA..GPIOD */
    (void)RCC_AHB1ENR; /* the clock needs two cycles before the first access */
}

/* ---- serial ------------------------------------------------------------- */
/* Rings as on the AVR: the USART1 vector only moves bytes (RXNE -> RX ring; TXE, while TXEIE is on,
 * TX ring -> DR); the loop copies in and out. Writes never wait for the line: hal_uart_write takes
 * what fits and hal_uart_tx_space says how much will. After queueing, the writer also feeds DR while
 * TXE is set (with the vector masked): on silicon that is one or two bytes before TXE clears and
 * the vector takes over; under QEMU, which completes every byte at once and never raises TXE,
 * it sends everything there and then. */
#define IRQ_USART1 37u
#define USART_SR_ORE (1u << 3)
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TXE (1u << 7)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TXEIE (1u << 7)
#define UART_RX_SIZE 256u /* powers of two: the indices wrap with a mask */
#define UART_TX_SIZE 512u

static volatile uint8_t s_rx[UART_RX_SIZE];
static volatile uint16_t s_rx_head; /* written by the vector */
static volatile uint16_t s_rx_tail; /* written by the loop */
static volatile uint8_t s_tx[UART_TX_SIZE];
static volatile uint16_t s_tx_head; /* written by the loop */
static volatile uint16_t s_tx_tail; /* written by the vector (or the loop with the vector masked) */

void USART1_IRQHandler(void)
{
    uint32_t sr = USART1_SR;
    if ((sr & (USART_SR_RXNE | USART_SR_ORE)) != 0u) {
        uint8_t b = (uint8_t)USART1_DR; /* clears RXNE (and ORE after the SR read) */
        uint16_t next = (uint16_t)((s_rx_head + 1u) & (UART_RX_SIZE - 1u));
        if (next != s_rx_tail && (sr & USART_SR_RXNE) != 0u) { /* a full ring drops the byte */
            s_rx[s_rx_head] = b;
            s_rx_head = next;
        }
    }
    if ((USART1_CR1 & USART_CR1_TXEIE) != 0u && (sr & USART_SR_TXE) != 0u) {
        if (s_tx_tail != s_tx_head) {
            USART1_DR = s_tx[s_tx_tail];
            s_tx_tail = (uint16_t)((s_tx_tail + 1u) & (UART_TX_SIZE - 1u));
        } else {
            USART1_CR1 &= ~USART_CR1_TXEIE; /* empty: off until the next write */
        }
    }
}

/* 16x oversampling (OVER8 = 0, RM0090 30.3.4): USARTDIV = f_PCLK / (16 baud), held in BRR as 12.4
 * fixed point (DIV_Mantissa, DIV_Fraction), i.e. BRR = 16 USARTDIV = f_PCLK / baud; rounded to the
 * nearest sixteenth (a fraction that rounds up to 16 carries into the mantissa by itself). The
 * rate is then f_PCLK / BRR: from the 84 MHz APB2 within 0.03 % of 9600..115200, 0.11 % at 230400. */
static uint32_t usart_brr(uint32_t pclk_hz, uint32_t baud) { return units_div_round_u32(pclk_hz, baud); }

void hal_uart_init(uint8_t port, uint32_t baud)
{
    if (port != HAL_UART_LINK || baud == 0u || baud > APB2_HZ / 16u) {
        return; /* USARTDIV below 1 cannot be set */
    }
    gpio_clocks_on();
    gpio_config(BOARD_UART_TX_PIN, GPIO_MODE_AF, GPIO_PULL_NONE, BOARD_UART_AF);
    gpio_config(BOARD_UART_RX_PIN, GPIO_MODE_AF, GPIO_PULL_UP, BOARD_UART_AF);
    RCC_APB2ENR |= RCC_APB2ENR_USART1;
    (void)RCC_APB2ENR;
    s_rx_head = s_rx_tail = 0u;
    s_tx_head = s_tx_tail = 0u;
    USART1_BRR = usart_brr(APB2_HZ, baud);
    USART1_CR1 = (1u << 13) | (1u << 3) | (1u << 2) | USART_CR1_RXNEIE; /* UE, TE, RE, RXNEIE */
    NVIC_ISER(IRQ_USART1 >> 5) = 1u << (IRQ_USART1 & 31u);
}

uint16_t hal_uart_tx_space(uint8_t port)
{
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    return (uint16_t)((s_tx_tail - s_tx_head - 1u) & (UART_TX_SIZE - 1u));
}

uint16_t hal_uart_write(uint8_t port, const uint8_t *data, uint16_t len)
{
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    uint16_t room = hal_uart_tx_space(port);
    uint16_t n = len < room ? len : room;
    uint16_t head = s_tx_head;
    for (uint16_t i = 0; i < n; i++) {
        s_tx[head] = data[i];
        head = (uint16_t)((head + 1u) & (UART_TX_SIZE - 1u));
    }
    hal_irq_state_t st = hal_irq_save();
    s_tx_head = head;
    while (s_tx_tail != s_tx_head && (USART1_SR & USART_SR_TXE) != 0u) {
        USART1_DR = s_tx[s_tx_tail];
        s_tx_tail = (uint16_t)((s_tx_tail + 1u) & (UART_TX_SIZE - 1u));
    }
    if (s_tx_tail != s_tx_head) {
        USART1_CR1 |= USART_CR1_TXEIE;
    }
    hal_irq_restore(st);
    return n;
}

uint16_t hal_uart_read(uint8_t port, uint8_t *data, uint16_t max)
{
    uint16_t n = 0;
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    uint16_t tail = s_rx_tail;
    while (n < max && tail != s_rx_head) {
        data[n++] = s_rx[tail];
        tail = (uint16_t)((tail + 1u) & (UART_RX_SIZE - 1u));
    }
    s_rx_tail = tail;
    return n;
}

/* ---- EXTI: Hall encoders on their A pins' lines, echoes on one line each ------ */
static hal_encoder_edge_fn s_encoder_fn;
static uint8_t s_encoder_count;
static uint8_t s_encoder_hall; /* bit i: encoder i is a Hall wheel (EXTI on A), else timer-counted */
static hal_echo_edge_fn s_echo_fn;
static uint8_t s_sonar_count;

static void exti_route(uint8_t line, uint8_t port)
{
    uint32_t shift = 4u * (line & 3u);
    SYSCFG_EXTICR(line >> 2) = (SYSCFG_EXTICR(line >> 2) & ~(0xFu << shift)) | ((uint32_t)port << shift);
}

static void exti_vectors_on(void)
{
    for (uint32_t irq = IRQ_EXTI0; irq <= IRQ_EXTI0 + 4u; irq++) {
        NVIC_ISER(irq >> 5) = 1u << (irq & 31u);
    }
    NVIC_ISER(IRQ_EXTI9_5 >> 5) = 1u << (IRQ_EXTI9_5 & 31u);
    NVIC_ISER(IRQ_EXTI15_10 >> 5) = 1u << (IRQ_EXTI15_10 & 31u);
}

/* Both edges of the lines in mask, stale pending edges dropped, then unmasked. */
static void exti_lines_on(uint32_t mask)
{
    RCC_APB2ENR |= RCC_APB2ENR_SYSCFG;
    (void)RCC_APB2ENR;
    EXTI_RTSR |= mask;
    EXTI_FTSR |= mask;
    EXTI_PR = mask;
    EXTI_IMR |= mask;
    exti_vectors_on();
}

/* One vector's lines: read which fired, clear them, sample levels and the time, and hand the
 * edges on. A line counts as fired when EXTI_PR has it or EXTI_SWIER does: on silicon a SWIER
 * write sets PR too (and clearing PR clears SWIER), QEMU 7.2 only stores SWIER, so software
 * edges (the QEMU tests, a board self-test) take the same path as pin edges. */
static void exti_service(uint32_t lines)
{
    uint32_t soft = EXTI_SWIER;
    uint32_t fired = (EXTI_PR | soft) & EXTI_IMR & lines;
    if (fired == 0u) {
        return;
    }
    EXTI_PR = fired;
    if (soft & fired) {
        EXTI_SWIER = soft & ~fired;
    }
    uint32_t t_us = hal_time_us();
    uint32_t hall = fired & BOARD_HALL_LINES_MASK;
    if (hall != 0u && s_encoder_fn != 0) {
        for (uint8_t i = 0; i < s_encoder_count; i++) {
            uint8_t line = BOARD_PIN_NUM(s_enc_a_pin[i]);
            if ((s_encoder_hall & (1u << i)) != 0u && (hall & (1u << line)) != 0u) {
                uint8_t a = (uint8_t)((GPIO_IDR(BOARD_PIN_PORT(s_enc_a_pin[i])) >> line) & 1u);
                s_encoder_fn(i, (uint8_t)(a << 1), t_us); /* B = 0: not sampled (hal.h) */
            }
        }
    }
    uint32_t echo = fired & BOARD_ECHO_LINES_MASK;
    if (echo != 0u && s_echo_fn != 0) {
        for (uint8_t i = 0; i < s_sonar_count; i++) {
            uint8_t line = BOARD_PIN_NUM(s_echo_pin[i]);
            if ((echo & (1u << line)) != 0u) {
                uint8_t level = (uint8_t)((GPIO_IDR(BOARD_PIN_PORT(s_echo_pin[i])) >> line) & 1u);
                s_echo_fn(i, level, t_us);
            }
        }
    }
}

void EXTI0_IRQHandler(void) { exti_service(1u << 0); }
void EXTI1_IRQHandler(void) { exti_service(1u << 1); }
void EXTI2_IRQHandler(void) { exti_service(1u << 2); }
void EXTI3_IRQHandler(void) { exti_service(1u << 3); }
void EXTI4_IRQHandler(void) { exti_service(1u << 4); }
void EXTI9_5_IRQHandler(void) { exti_service(0x03E0u); }
void EXTI15_10_IRQHandler(void) { exti_service(0xFC00u); }

/* ---- timers -------------------------------------------------------------- */
/* TIM2..7, TIM12..14 sit on APB1 at 0x40000000 + 0x400 k with enable bit k of RCC_APB1ENR; TIM1/8 on
 * APB2 at 0x40010000 / 0x40010400 (bits 0, 1), TIM9..11 at 0x40014000 + 0x400 k (bits 16 + k)
 * (RM0090 2.3 memory map, 7.3.13 RCC_APB1ENR, 7.3.14 RCC_APB2ENR). */
static bool timer_on_apb2(uint32_t base) { return base >= 0x40010000u; }

static void timer_clock_on(uint32_t base)
{
    if (!timer_on_apb2(base)) {
        RCC_APB1ENR |= 1u << ((base - 0x40000000u) / 0x400u);
        (void)RCC_APB1ENR;
    } else if (base < 0x40014000u) {
        RCC_APB2ENR |= 1u << ((base - 0x40010000u) / 0x400u);
        (void)RCC_APB2ENR;
    } else {
        RCC_APB2ENR |= 1u << (16u + (base - 0x40014000u) / 0x400u);
        (void)RCC_APB2ENR;
    }
}

/* ---- encoders ------------------------------------------------------------
 * Quadrature wheels: the timer's encoder interface (RM0090 17.3.16 TIM1/8, 18.3.12 TIM2..5),
 * SMS = 011: the counter steps on every edge of TI1FP1 and TI2FP2, up when TI1 leads TI2, with no
 * CPU per edge. Input filter ICxF = 1100 (f_DTS / 16, N = 8) on a 42 MHz f_DTS (CKD: /2 of the
 * 84 MHz APB1 timer clock, /4 of the 168 MHz APB2 one): a level counts after 8 equal samples
 * 0.38 us apart, so glitches up to 3.0 us are dropped and a line's edges must be >= 3.4 us apart:
 * up to ~290 k edges/s per line, ~580 k counts/s x4 from a 90 degree, 50 % duty encoder.
 * Counter 16 bit (ARR 0xFFFF) on every timer; hal_encoder_poll() folds the signed 16-bit step
 * since the previous call into the record, so it must run at least every 32767 counts.
 * Hall wheels: A is a GPIO input (pull-up) on EXTI, both edges; the timer stays off. */
#define ENC_CCMR1 ((1u << 0) | (0xCu << 4) | (1u << 8) | (0xCu << 12)) /* CC1S = CC2S = 01 (TI1, TI2), IC1F = IC2F = 1100 */
static uint16_t s_enc_cnt[HAL_ENCODER_MAX]; /* CNT folded so far */

static void encoder_timer_init(uint32_t base)
{
    TIM_REG(base, TIM_CR1) = 0u;
    TIM_REG(base, TIM_SMCR) = TIM_SMCR_SMS_ENCODER3;
    TIM_REG(base, TIM_CCMR1) = ENC_CCMR1;
    TIM_REG(base, TIM_CCER) = 0u; /* CC1P = CC2P = 0: inputs not inverted; no capture */
    TIM_REG(base, TIM_PSC) = 0u;
    TIM_REG(base, TIM_ARR) = 0xFFFFu;
    TIM_REG(base, TIM_EGR) = TIM_EGR_UG;
    TIM_REG(base, TIM_CNT) = 0u;
    TIM_REG(base, TIM_CR1) = TIM_CR1_CKD(timer_on_apb2(base) ? 2u : 1u) | TIM_CR1_CEN;
}

/* Fold a timer count into encoder i's record: the signed step since the last fold, raw-forward
 * when A leads B (encoder_isr.h), stamped with t_us (the poll's time: the steps happened since the
 * previous poll). */
static void encoder_fold_count(uint8_t i, uint16_t cnt, uint32_t t_us)
{
    int32_t d = (int16_t)(uint16_t)(cnt - s_enc_cnt[i]);
    s_enc_cnt[i] = cnt;
    if ((BOARD_ENCODER_A_ON_CH2 & (1u << i)) != 0u) {
        d = -d; /* A on TI2: the counter goes up when B leads */
    }
    encoder_isr_t *e = &encoder_isr_state[i];
    uint16_t stamp = (uint16_t)(t_us >> ENCODER_STAMP_SHIFT);
    if (d > 0) {
        e->fwd = (uint16_t)(e->fwd + (uint16_t)d);
        e->fwd_stamp = stamp;
    } else if (d < 0) {
        e->back = (uint16_t)(e->back + (uint16_t)-d);
        e->back_stamp = stamp;
    }
}

void hal_encoder_attach(uint8_t count, uint8_t hall_mask, hal_encoder_edge_fn fn)
{
    if (count > HAL_ENCODER_MAX) {
        count = HAL_ENCODER_MAX;
    }
    hal_irq_state_t s = hal_irq_save();
    EXTI_IMR &= ~(uint32_t)BOARD_HALL_LINES_MASK;
    s_encoder_fn = fn;
    s_encoder_count = fn != 0 ? count : 0u;
    s_encoder_hall = (uint8_t)(hall_mask & ((1u << s_encoder_count) - 1u));
    gpio_clocks_on();
    uint32_t hall_lines = 0u;
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        uint32_t base = s_enc_timer[i];
        TIM_REG(base, TIM_CR1) = 0u; /* stopped unless counting a wheel below */
        if (i >= s_encoder_count) {
            continue;
        }
        uint8_t a = s_enc_a_pin[i];
        if ((s_encoder_hall & (1u << i)) != 0u) {
            gpio_config(a, GPIO_MODE_IN, GPIO_PULL_UP, 0u); /* open-collector Hall sensor */
            gpio_config(s_enc_b_pin[i], GPIO_MODE_IN, GPIO_PULL_DOWN, 0u); /* unused: a defined 0 */
            exti_route(BOARD_PIN_NUM(a), BOARD_PIN_PORT(a));
            hall_lines |= 1u << BOARD_PIN_NUM(a);
        } else {
            timer_clock_on(base);
            gpio_config(a, GPIO_MODE_AF, GPIO_PULL_UP, s_enc_af[i]);
            gpio_config(s_enc_b_pin[i], GPIO_MODE_AF, GPIO_PULL_UP, s_enc_af[i]);
            encoder_timer_init(base);
            s_enc_cnt[i] = (uint16_t)TIM_REG(base, TIM_CNT);
        }
    }
    if (hall_lines != 0u) {
        exti_lines_on(hall_lines);
    }
    hal_irq_restore(s);
}

void hal_encoder_poll(void)
{
    uint32_t t_us = hal_time_us();
    for (uint8_t i = 0; i < s_encoder_count; i++) {
        if ((s_encoder_hall & (1u << i)) == 0u) {
            encoder_fold_count(i, (uint16_t)TIM_REG(s_enc_timer[i], TIM_CNT), t_us);
        }
    }
}

/* ---- sonars --------------------------------------------------------------- */
static uint8_t s_trigger_shared;                       /* bit t: trigger pin t fires several attached sonars */
static uint8_t s_trigger_pulsed;                       /* bit t: s_trigger_us[t] is the time of a pulse */
static uint32_t s_trigger_us[BOARD_SONAR_TRIGGER_COUNT];

void hal_sonar_attach(uint8_t count, hal_echo_edge_fn fn)
{
    if (count > HAL_SONAR_MAX) {
        count = HAL_SONAR_MAX;
    }
    hal_irq_state_t s = hal_irq_save();
    EXTI_IMR &= ~(uint32_t)BOARD_ECHO_LINES_MASK;
    s_echo_fn = fn;
    s_sonar_count = fn != 0 ? count : 0u;
    gpio_clocks_on();
    uint8_t used = 0u;
    s_trigger_shared = 0u;
    s_trigger_pulsed = 0u;
    uint32_t mask = 0u;
    for (uint8_t i = 0; i < count; i++) {
        uint8_t t = s_trigger_of[i];
        s_trigger_shared = (uint8_t)(s_trigger_shared | (used & (1u << t)));
        used = (uint8_t)(used | (1u << t));
        gpio_write(s_trigger_pin[t], false);
        gpio_config(s_trigger_pin[t], GPIO_MODE_OUT, GPIO_PULL_NONE, 0u);
        /* pull-down: an unplugged sensor reads a steady 0, not a floating line */
        gpio_config(s_echo_pin[i], GPIO_MODE_IN, GPIO_PULL_DOWN, 0u);
        exti_route(BOARD_PIN_NUM(s_echo_pin[i]), BOARD_PIN_PORT(s_echo_pin[i]));
        mask |= 1u << BOARD_PIN_NUM(s_echo_pin[i]);
    }
    if (fn != 0 && mask != 0u) {
        exti_lines_on(mask);
    }
    hal_irq_restore(s);
}

void hal_sonar_poll(void) {} /* the EXTI handler calls the hook itself */

/* 10 us on sonar idx's trigger pin. A pin shared by several attached sonars (board.h) is pulsed
 * once per group firing: a call within BOARD_SONAR_TRIGGER_SHARED_US of its last pulse returns,
 * the sonar having fired with that pulse. */
void hal_sonar_trigger(uint8_t idx)
{
    if (idx >= HAL_SONAR_MAX) {
        return;
    }
    uint8_t t = s_trigger_of[idx];
    uint8_t bit = (uint8_t)(1u << t);
    uint32_t now = hal_time_us();
    if ((s_trigger_shared & s_trigger_pulsed & bit) != 0u &&
        (uint32_t)(now - s_trigger_us[t]) < BOARD_SONAR_TRIGGER_SHARED_US) {
        return;
    }
    s_trigger_pulsed = (uint8_t)(s_trigger_pulsed | bit);
    s_trigger_us[t] = now;
    gpio_write(s_trigger_pin[t], true);
    hal_delay_us(BOARD_SONAR_TRIGGER_US);
    gpio_write(s_trigger_pin[t], false);
}

/* ---- actuators ------------------------------------------------------------
 * Servo / ESC on TIM9 (APB2, 168 MHz timer clock): PSC 167 -> 1 MHz, ARR 19999 -> 50 Hz.
 * H-bridges on TIM10 / TIM11 (APB2): PSC 0, 8400 ticks -> 20 kHz. PWM mode 1 with preload. */
#define SERVO_TIMER BOARD_TIM9_BASE
#define SERVO_TIMER_HZ APB2_TIMER_HZ
#define SERVO_PRESCALER (SERVO_TIMER_HZ / 1000000u)
#define HBRIDGE_TIMER_HZ APB2_TIMER_HZ
#define HBRIDGE_PERIOD_TICKS (HBRIDGE_TIMER_HZ / BOARD_HBRIDGE_PWM_HZ) /* 8400 at 20 kHz */
_Static_assert(SERVO_TIMER_HZ % 1000000u == 0u && SERVO_PRESCALER <= 65536u, "1 us servo ticks");
_Static_assert(HBRIDGE_PERIOD_TICKS <= 65536u, "16-bit H-bridge period");

static uint32_t servo_ccr(uint16_t pulse_us)
{
    return pulse_us < 800u ? 800u : pulse_us > 2200u ? 2200u : pulse_us; /* 1 MHz timer: ticks = us */
}

void hal_servo_write_us(uint8_t channel, uint16_t pulse_us)
{
    if (channel == HAL_SERVO_STEER) {
        TIM_REG(SERVO_TIMER, TIM_CCR1) = servo_ccr(pulse_us);
    } else if (channel == HAL_SERVO_THROTTLE) {
        TIM_REG(SERVO_TIMER, TIM_CCR2) = servo_ccr(pulse_us);
    }
}

/* duty 255 = the whole period (CCR = ARR + 1: output always on in PWM mode 1); 0: always off. */
static uint32_t hbridge_ccr(uint8_t duty) { return (uint32_t)duty * HBRIDGE_PERIOD_TICKS / 255u; }

void hal_pwm_write_duty(uint8_t channel, uint8_t duty, bool reverse)
{
    if (channel >= HAL_PWM_MAX) {
        return;
    }
    gpio_write(s_hbridge_dir_pin[channel], reverse);
    TIM_REG(s_hbridge_timer[channel], TIM_CCR1) = hbridge_ccr(duty);
}

/* PWM mode 1 with preload on CH1 (and CH2 when two_channels), outputs enabled, counter on
 * (RM0090 19.4: TIM9 has CH1/CH2, TIM10/11 CH1 only). */
static void pwm_timer_init(uint32_t base, bool two_channels, uint32_t prescaler, uint32_t period_ticks, uint32_t ccr)
{
    timer_clock_on(base);
    TIM_REG(base, TIM_CR1) = 0u;
    TIM_REG(base, TIM_PSC) = prescaler - 1u;
    TIM_REG(base, TIM_ARR) = period_ticks - 1u;
    TIM_REG(base, TIM_CCR1) = ccr;
    uint32_t ccmr = (6u << 4) | (1u << 3); /* OC1M = PWM mode 1, OC1PE */
    uint32_t ccer = 1u << 0;               /* CC1E */
    if (two_channels) {
        TIM_REG(base, TIM_CCR2) = ccr;
        ccmr |= (6u << 12) | (1u << 11); /* OC2M, OC2PE */
        ccer |= 1u << 4;                 /* CC2E */
    }
    TIM_REG(base, TIM_CCMR1) = ccmr;
    TIM_REG(base, TIM_CCER) = ccer;
    TIM_REG(base, TIM_EGR) = TIM_EGR_UG; /* load PSC, ARR, CCRs */
    TIM_REG(base, TIM_CR1) = TIM_CR1_ARPE | TIM_CR1_CEN;
}

static void actuators_init(void)
{
    pwm_timer_init(SERVO_TIMER, true, SERVO_PRESCALER, BOARD_SERVO_PERIOD_US, 1500u);
    for (uint8_t i = 0; i < HAL_PWM_MAX; i++) {
        pwm_timer_init(s_hbridge_timer[i], false, 1u, HBRIDGE_PERIOD_TICKS, 0u);
    }
    for (uint8_t i = 0; i < HAL_SERVO_MAX; i++) {
        gpio_config(s_servo_pin[i], GPIO_MODE_AF, GPIO_PULL_NONE, BOARD_SERVO_AF);
    }
    for (uint8_t i = 0; i < HAL_PWM_MAX; i++) {
        gpio_config(s_hbridge_pwm_pin[i], GPIO_MODE_AF, GPIO_PULL_NONE, BOARD_HBRIDGE_AF);
        gpio_write(s_hbridge_dir_pin[i], false);
        gpio_config(s_hbridge_dir_pin[i], GPIO_MODE_OUT, GPIO_PULL_NONE, 0u);
    }
}

/* ---- EEPROM ------------------------------------------------------------- */
/* 4 KB in two 16 KB flash sectors (RM0090 3.3: sectors 1 and 2 at 0x08004000 / 0x08008000; the
 * linker script puts the vectors in sector 0 and the code from sector 3 on): 3070 byte changes fit
 * in a sector before the store moves to the other one, erasing it (16 KB: typ. 250 ms, max 500 ms,
 * during which nothing runs from flash, interrupts included). Erase and program run from RAM and
 * refresh the watchdog while the flash is busy. Under QEMU the flash controller is not modelled:
 * the first program fails its read-back and the store keeps its values in RAM until reset. */
#define FLASH_KEYR REG32(0x40023C04u)
#define FLASH_SR REG32(0x40023C0Cu)
#define FLASH_CR REG32(0x40023C10u)
#define FLASH_SR_BSY (1u << 16)
#define FLASH_SR_ERRORS (0xF2u) /* PGSERR PGPERR PGAERR WRPERR OPERR */
#define FLASH_CR_PG (1u << 0)
#define FLASH_CR_SER (1u << 1)
#define FLASH_CR_SNB(n) ((uint32_t)(n) << 3)
#define FLASH_CR_PSIZE_X32 (2u << 8)
#define FLASH_CR_STRT (1u << 16)
#define FLASH_CR_LOCK (1u << 31)
#define FLASH_BUSY_LIMIT 100000000u /* ~2.4 s of polls at 168 MHz: more than a sector erase's 0.5 s max */
#define EEPROM_EMU_SIZE 4096u
#define EEPROM_SECTOR_FIRST 1u
#define EEPROM_BANK_BYTES 0x4000u
#define EEPROM_BANK_ADDR(b) (0x08004000u + EEPROM_BANK_BYTES * (uint32_t)(b))

#define RAMFUNC __attribute__((section(".ramfunc"), noinline, long_call))

/* One erase (word_addr NULL) or one word program, from RAM: the flash stalls every fetch from it
 * until it is done. Returns the status register's error bits (0: done). */
RAMFUNC static uint32_t flash_op_ram(uint32_t cr, volatile uint32_t *word_addr, uint32_t word)
{
    FLASH_SR = FLASH_SR_ERRORS | 1u; /* write-1-to-clear, EOP too */
    FLASH_CR = cr;
    if (word_addr != 0) {
        *word_addr = word;
    } else {
        FLASH_CR = cr | FLASH_CR_STRT;
    }
    for (uint32_t n = 0; (FLASH_SR & FLASH_SR_BSY) != 0u && n < FLASH_BUSY_LIMIT; n++) {
        IWDG_KR = 0xAAAAu;
    }
    FLASH_CR = 0u;
    return FLASH_SR & (FLASH_SR_ERRORS | FLASH_SR_BSY);
}

static bool flash_op(uint32_t cr, volatile uint32_t *word_addr, uint32_t word)
{
    if ((FLASH_CR & FLASH_CR_LOCK) != 0u) {
        FLASH_KEYR = 0x45670123u;
        FLASH_KEYR = 0xCDEF89ABu;
    }
    hal_irq_state_t st = hal_irq_save();
    uint32_t err = flash_op_ram(cr | FLASH_CR_PSIZE_X32, word_addr, word);
    hal_irq_restore(st);
    FLASH_CR = FLASH_CR_LOCK;
    /* the data cache may hold what the sector read before: reset it (DCEN off, DCRST, DCEN on) */
    uint32_t acr = FLASH_ACR;
    FLASH_ACR = acr & ~(1u << 10);
    FLASH_ACR = (acr & ~(1u << 10)) | (1u << 12);
    FLASH_ACR = acr;
    return err == 0u;
}

static bool eeprom_erase(uint8_t bank)
{
    return flash_op(FLASH_CR_SER | FLASH_CR_SNB(EEPROM_SECTOR_FIRST + bank), 0, 0u);
}

static bool eeprom_program(uint8_t bank, uint32_t offset, uint32_t word)
{
    return flash_op(FLASH_CR_PG, (volatile uint32_t *)(EEPROM_BANK_ADDR(bank) + offset), word);
}

static const fe_flash_t s_eeprom_flash = {
    EEPROM_BANK_BYTES,
    {(const volatile uint8_t *)EEPROM_BANK_ADDR(0), (const volatile uint8_t *)EEPROM_BANK_ADDR(1)},
    eeprom_erase,
    eeprom_program,
};
static fe_t s_eeprom;
static uint8_t s_eeprom_mirror[EEPROM_EMU_SIZE];
static bool s_eeprom_ready;

static void eeprom_ready(void)
{
    if (!s_eeprom_ready) {
        fe_init(&s_eeprom, &s_eeprom_flash, s_eeprom_mirror, EEPROM_EMU_SIZE);
        s_eeprom_ready = true;
    }
}

uint16_t hal_eeprom_size(void) { return (uint16_t)EEPROM_EMU_SIZE; }

void hal_eeprom_read(uint16_t addr, void *dst, uint16_t len)
{
    eeprom_ready();
    fe_read(&s_eeprom, addr, dst, len);
}

/* Busy while the active sector has no room for another byte: the store then moves to the other sector,
 * an erase that stalls everything running from flash for up to 0.5 s, and that happens only in
 * hal_eeprom_idle(), at rest. */
bool hal_eeprom_busy(void)
{
    eeprom_ready();
    return !fe_has_room(&s_eeprom);
}

bool hal_eeprom_write_byte(uint16_t addr, uint8_t value)
{
    eeprom_ready();
    return fe_write(&s_eeprom, addr, &value, 1u);
}

/* At rest: move to the other sector once the active one is half full (or full, when writes wait for it),
 * so the erase's stall falls here and never while driving. */
void hal_eeprom_idle(void)
{
    if (s_eeprom_ready) {
        (void)fe_compact_if_fuller_than(&s_eeprom, 50u);
    }
}

/* ---- watchdog and reset cause ------------------------------------------- */
/* IWDG timeout = (4 << pr) * (rlr + 1) / LSI_HZ: the smallest prescaler whose 12-bit reload
 * reaches timeout_ms (finest resolution), saturating at /256 * 4096 = 32.8 s. The LSI is only
 * 17..47 kHz (DS8626), so the real timeout is 0.68..1.9 times the nominal one. */
static void iwdg_setting(uint16_t timeout_ms, uint32_t *pr, uint32_t *rlr)
{
    uint32_t lsi_ticks = (uint32_t)timeout_ms * (LSI_HZ / 1000u);
    uint32_t p = 0u;
    while (p < 6u && lsi_ticks / (4u << p) > 4096u) {
        p++;
    }
    uint32_t reload = lsi_ticks / (4u << p);
    *pr = p;
    *rlr = reload == 0u ? 0u : reload > 4096u ? 4095u : reload - 1u;
}

/* Start first (0xCCCC also starts the LSI the PR/RLR update runs on), then unlock, set the
 * timeout, wait for the update (bounded) and reload. Once started it cannot be stopped. */
void hal_watchdog_start(uint16_t timeout_ms)
{
    uint32_t pr, rlr;
    iwdg_setting(timeout_ms, &pr, &rlr);
    IWDG_KR = 0xCCCCu;
    IWDG_KR = 0x5555u;
    IWDG_PR = pr;
    IWDG_RLR = rlr;
    for (uint32_t i = 0; i < 200000u && (IWDG_SR & 3u) != 0u; i++) { /* PVU, RVU */
    }
    IWDG_KR = 0xAAAAu;
}

void hal_watchdog_kick(void) { IWDG_KR = 0xAAAAu; }

/* The cause from RCC_CSR's reset flags (RM0090 7.3.21). Every reset drives NRST, so PINRSTF alone
 * means the pin; a power-on sets BORRSTF too. */
static hal_reset_cause_t reset_cause_of(uint32_t csr)
{
    if (csr & (RCC_CSR_IWDGRSTF | RCC_CSR_WWDGRSTF)) return HAL_RESET_WATCHDOG;
    if (csr & RCC_CSR_PORRSTF) return HAL_RESET_POWER_ON;
    if (csr & RCC_CSR_BORRSTF) return HAL_RESET_BROWN_OUT; /* BOR without POR */
    if (csr & (RCC_CSR_SFTRSTF | RCC_CSR_LPWRRSTF)) return HAL_RESET_OTHER;
    if (csr & RCC_CSR_PINRSTF) return HAL_RESET_EXTERNAL;
    return HAL_RESET_POWER_ON;
}

/* Read once and cleared (RMVF) on the first call, which main makes at boot. QEMU does not model
 * the RCC (reads 0): taken as a power-on. */
hal_reset_cause_t hal_reset_cause(void)
{
    static uint32_t s_csr;
    static bool s_read;
    if (!s_read) {
        s_read = true;
        s_csr = RCC_CSR;
        RCC_CSR |= RCC_CSR_RMVF;
    }
    return reset_cause_of(s_csr);
}

/* ---- init --------------------------------------------------------------- */
void hal_init(void)
{
    clock_init();
    SYST_CSR = 0u;
    SYST_RVR = SYSTICK_RELOAD - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 7u; /* core clock, interrupt, enable */
    gpio_clocks_on();
    actuators_init();
    __asm__ volatile("cpsie i");
}

#endif /* __arm__ */
