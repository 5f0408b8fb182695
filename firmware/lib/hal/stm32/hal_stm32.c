/*
 * STM32F405 backend of the AgNav HAL (register level after RM0090, no vendor library).
 * Pin map and the board assumed: board.h.
 *   link UART   USART1 PA9 TX / PA10 RX, interrupt-driven rings (RX 256 B, TX 512 B)
 *   time        SysTick at 1 kHz from the core clock + the current-value register
 *   servos      TIM3 CH1/CH2 (PA6, PA7), 50 Hz, 1 us resolution
 *   H-bridges   TIM4 CH1/CH2 (PB6, PB7), 20 kHz, 8-bit duty scaled to the period; DIR on GPIO
 *   encoders    EXTI lines 0..7 (PC0..PC7), both edges
 *   sonars      GPIO trigger pulse; echoes on EXTI lines 8..15, both edges
 *   watchdog    IWDG from the ~32 kHz LSI
 *   EEPROM      4 KB emulated in flash sectors 1 and 2 (lib/flash_eeprom; the linker script keeps
 *               code out of them), erase and program run from RAM
 *
 * Under QEMU netduinoplus2 (7.2) USART1, SysTick, NVIC, SYSCFG, EXTI's registers and TIM2..5
 * are modelled; GPIO, RCC, FLASH, IWDG and TIM1/8.. are "unimplemented" (reads 0, writes
 * ignored) and nothing drives an EXTI line from a pin. What that leaves untested is listed in
 * docs/firmware/hal_stm32.md. Every wait on a flag is bounded, so unmodelled blocks never hang.
 *
 * Built for the firmware (not for unit-test builds, which link the sim backend) and, under
 * other names, by test/test_hal_stm32 (AGNAV_HAL_STM32_UNDER_TEST).
 */
#if defined(__arm__) && (!defined(PIO_UNIT_TESTING) || defined(AGNAV_HAL_STM32_UNDER_TEST))

#include "../hal.h"
#include "board.h"
#include "flash_eeprom.h"

#include <string.h>

#define REG32(addr) (*(volatile uint32_t *)(addr))

#define RCC_CR REG32(0x40023800u)
#define RCC_PLLCFGR REG32(0x40023804u)
#define RCC_CFGR REG32(0x40023808u)
#define RCC_AHB1ENR REG32(0x40023830u)
#define RCC_APB1ENR REG32(0x40023840u)
#define RCC_APB2ENR REG32(0x40023844u)
#define RCC_CSR REG32(0x40023874u)
#define FLASH_ACR REG32(0x40023C00u)

#define USART1_SR REG32(0x40011000u)
#define USART1_DR REG32(0x40011004u)
#define USART1_BRR REG32(0x40011008u)
#define USART1_CR1 REG32(0x4001100Cu)

#define SYST_CSR REG32(0xE000E010u)
#define SYST_RVR REG32(0xE000E014u)
#define SYST_CVR REG32(0xE000E018u)
#define SCB_ICSR REG32(0xE000ED04u)
#define NVIC_ISER(n) REG32(0xE000E100u + 4u * (n))

/* GPIOx at 0x40020000 + 0x400 * x (RM0090 8.4) */
#define GPIO_REG(port, off) REG32(0x40020000u + 0x400u * (uint32_t)(port) + (off))
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

/* General-purpose timers (RM0090 18.4) */
#define TIM_REG(base, off) REG32((base) + (off))
#define TIM3_BASE 0x40000400u
#define TIM4_BASE 0x40000800u
#define TIM_CR1 0x00u
#define TIM_EGR 0x14u
#define TIM_CCMR1 0x18u
#define TIM_CCER 0x20u
#define TIM_PSC 0x28u
#define TIM_ARR 0x2Cu
#define TIM_CCR1 0x34u
#define TIM_CCR2 0x38u

#define IWDG_KR REG32(0x40003000u)
#define IWDG_PR REG32(0x40003004u)
#define IWDG_RLR REG32(0x40003008u)
#define IWDG_SR REG32(0x4000300Cu)

#define CORE_HZ 168000000u /* PLL from the 16 MHz HSI; QEMU netduinoplus2 runs at this clock too */
#define APB1_TIMER_HZ (CORE_HZ / 2u) /* APB1 = HCLK / 4, its timers run at twice that */
#define APB2_HZ (CORE_HZ / 2u)
#define SYSTICK_RELOAD (CORE_HZ / 1000u)
#define HBRIDGE_PERIOD_TICKS (APB1_TIMER_HZ / BOARD_HBRIDGE_PWM_HZ) /* 4200 at 20 kHz */
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

#define ECHO_LINE_FIRST 8u
#define ECHO_NO_OWNER 0xFFu

static const uint8_t s_servo_pin[HAL_SERVO_MAX] = BOARD_SERVO_PINS;
static const uint8_t s_hbridge_pwm_pin[HAL_PWM_MAX] = BOARD_HBRIDGE_PWM_PINS;
static const uint8_t s_hbridge_dir_pin[HAL_PWM_MAX] = BOARD_HBRIDGE_DIR_PINS;
static const uint8_t s_trigger_pin[HAL_SONAR_MAX] = BOARD_SONAR_TRIGGER_PINS;
static const uint8_t s_echo_pin[HAL_SONAR_MAX] = BOARD_SONAR_ECHO_PINS;

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

void hal_uart_init(uint8_t port, uint32_t baud)
{
    if (port != HAL_UART_LINK || baud == 0u) {
        return;
    }
    gpio_clocks_on();
    gpio_config(BOARD_UART_TX_PIN, GPIO_MODE_AF, GPIO_PULL_NONE, BOARD_UART_AF);
    gpio_config(BOARD_UART_RX_PIN, GPIO_MODE_AF, GPIO_PULL_UP, BOARD_UART_AF);
    RCC_APB2ENR |= (1u << 4);
    (void)RCC_APB2ENR;
    s_rx_head = s_rx_tail = 0u;
    s_tx_head = s_tx_tail = 0u;
    USART1_BRR = APB2_HZ / baud; /* 16x oversampling: mantissa.fraction in one divide */
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

/* ---- EXTI: encoders on lines 0..7, echoes on lines 8..15 ------------------ */
static hal_encoder_edge_fn s_encoder_fn;
static uint8_t s_encoder_count;
static hal_echo_edge_fn s_echo_fn;
static uint8_t s_sonar_count;
static uint8_t s_echo_owner[16u - ECHO_LINE_FIRST]; /* sonar routed to each echo line */

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
    RCC_APB2ENR |= (1u << 14); /* SYSCFG */
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
    uint32_t enc = fired & BOARD_ENCODER_LINES_MASK;
    if (enc != 0u && s_encoder_fn != 0) {
        uint32_t idr = GPIO_IDR(BOARD_ENCODER_PORT);
        for (uint8_t i = 0; i < s_encoder_count; i++) {
            if (enc & (3u << (2u * i))) { /* one call per encoder, even if A and B both moved */
                uint8_t a = (uint8_t)((idr >> (2u * i)) & 1u);
                uint8_t b = (uint8_t)((idr >> (2u * i + 1u)) & 1u);
                s_encoder_fn(i, (uint8_t)((a << 1) | b), t_us);
            }
        }
    }
    uint32_t echo = fired & BOARD_ECHO_LINES_MASK;
    if (echo != 0u && s_echo_fn != 0) {
        for (uint8_t line = ECHO_LINE_FIRST; line < 16u; line++) {
            uint8_t idx = s_echo_owner[line - ECHO_LINE_FIRST];
            if ((echo & (1u << line)) && idx < s_sonar_count) {
                uint8_t level = (uint8_t)((GPIO_IDR(BOARD_PIN_PORT(s_echo_pin[idx])) >> line) & 1u);
                s_echo_fn(idx, level, t_us);
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

void hal_encoder_attach(uint8_t count, hal_encoder_edge_fn fn)
{
    if (count > HAL_ENCODER_MAX) {
        count = HAL_ENCODER_MAX;
    }
    uint32_t mask = (1u << (2u * count)) - 1u;
    hal_irq_state_t s = hal_irq_save();
    EXTI_IMR &= ~(uint32_t)BOARD_ENCODER_LINES_MASK;
    s_encoder_fn = fn;
    s_encoder_count = fn != 0 ? count : 0u;
    gpio_clocks_on();
    for (uint8_t line = 0; line < 2u * count; line++) {
        /* pull-ups: open-collector Hall sensors; B of a single-channel wheel reads 1 */
        gpio_config(BOARD_PIN(BOARD_ENCODER_PORT, line), GPIO_MODE_IN, GPIO_PULL_UP, 0u);
        exti_route(line, BOARD_ENCODER_PORT);
    }
    if (fn != 0 && mask != 0u) {
        exti_lines_on(mask);
    }
    hal_irq_restore(s);
}

/* Route the echo line of sonar idx to idx's port (its pair partner loses it). Masked while
 * switching; an edge the switch itself makes (partner high, idx low) is dropped. */
static void echo_route(uint8_t idx)
{
    uint8_t line = BOARD_PIN_NUM(s_echo_pin[idx]);
    uint32_t bit = 1u << line;
    hal_irq_state_t s = hal_irq_save();
    if (s_echo_owner[line - ECHO_LINE_FIRST] != idx) {
        uint32_t was_on = EXTI_IMR & bit;
        EXTI_IMR &= ~bit;
        exti_route(line, BOARD_PIN_PORT(s_echo_pin[idx]));
        EXTI_PR = bit;
        s_echo_owner[line - ECHO_LINE_FIRST] = idx;
        EXTI_IMR |= was_on;
    }
    hal_irq_restore(s);
}

void hal_sonar_attach(uint8_t count, hal_echo_edge_fn fn)
{
    if (count > HAL_SONAR_MAX) {
        count = HAL_SONAR_MAX;
    }
    hal_irq_state_t s = hal_irq_save();
    EXTI_IMR &= ~(uint32_t)BOARD_ECHO_LINES_MASK;
    s_echo_fn = fn;
    s_sonar_count = fn != 0 ? count : 0u;
    memset(s_echo_owner, ECHO_NO_OWNER, sizeof s_echo_owner);
    gpio_clocks_on();
    uint32_t mask = 0u;
    for (uint8_t i = 0; i < count; i++) {
        gpio_write(s_trigger_pin[i], false);
        gpio_config(s_trigger_pin[i], GPIO_MODE_OUT, GPIO_PULL_NONE, 0u);
        /* pull-down: an unplugged sensor reads a steady 0, not a floating line */
        gpio_config(s_echo_pin[i], GPIO_MODE_IN, GPIO_PULL_DOWN, 0u);
        uint8_t line = BOARD_PIN_NUM(s_echo_pin[i]);
        if (s_echo_owner[line - ECHO_LINE_FIRST] == ECHO_NO_OWNER) { /* lower idx first */
            s_echo_owner[line - ECHO_LINE_FIRST] = i;
            exti_route(line, BOARD_PIN_PORT(s_echo_pin[i]));
        }
        mask |= 1u << line;
    }
    if (fn != 0 && mask != 0u) {
        exti_lines_on(mask);
    }
    hal_irq_restore(s);
}

void hal_sonar_poll(void) {} /* the EXTI handler calls the hook itself */

void hal_sonar_trigger(uint8_t idx)
{
    if (idx >= HAL_SONAR_MAX) {
        return;
    }
    if (idx < s_sonar_count) {
        echo_route(idx);
    }
    gpio_write(s_trigger_pin[idx], true);
    hal_delay_us(BOARD_SONAR_TRIGGER_US);
    gpio_write(s_trigger_pin[idx], false);
}

/* ---- actuators ---------------------------------------------------------- */
void hal_servo_write_us(uint8_t channel, uint16_t pulse_us)
{
    if (pulse_us < 800u) {
        pulse_us = 800u;
    } else if (pulse_us > 2200u) {
        pulse_us = 2200u;
    }
    if (channel == HAL_SERVO_STEER) {
        TIM_REG(TIM3_BASE, TIM_CCR1) = pulse_us; /* 1 MHz timer: ticks = us */
    } else if (channel == HAL_SERVO_THROTTLE) {
        TIM_REG(TIM3_BASE, TIM_CCR2) = pulse_us;
    }
}

/* duty 255 = the whole period (CCR = ARR + 1: output always on in PWM mode 1). */
static uint32_t hbridge_ccr(uint8_t duty) { return (uint32_t)duty * HBRIDGE_PERIOD_TICKS / 255u; }

void hal_pwm_write_duty(uint8_t channel, uint8_t duty, bool reverse)
{
    if (channel >= HAL_PWM_MAX) {
        return;
    }
    gpio_write(s_hbridge_dir_pin[channel], reverse);
    TIM_REG(TIM4_BASE, channel == 0u ? TIM_CCR1 : TIM_CCR2) = hbridge_ccr(duty);
}

/* PWM mode 1 with preload on CH1 and CH2, outputs enabled, counter on (RM0090 18.4.7..). */
static void pwm_timer_init(uint32_t base, uint32_t prescaler, uint32_t period_ticks, uint32_t ccr)
{
    TIM_REG(base, TIM_CR1) = 0u;
    TIM_REG(base, TIM_PSC) = prescaler - 1u;
    TIM_REG(base, TIM_ARR) = period_ticks - 1u;
    TIM_REG(base, TIM_CCR1) = ccr;
    TIM_REG(base, TIM_CCR2) = ccr;
    TIM_REG(base, TIM_CCMR1) = (6u << 4) | (1u << 3) | (6u << 12) | (1u << 11); /* OC1M, OC1PE, OC2M, OC2PE */
    TIM_REG(base, TIM_CCER) = (1u << 0) | (1u << 4);                         /* CC1E, CC2E */
    TIM_REG(base, TIM_EGR) = 1u;                                             /* UG: load PSC, ARR, CCRs */
    TIM_REG(base, TIM_CR1) = (1u << 7) | 1u;                                 /* ARPE, CEN */
}

static void actuators_init(void)
{
    RCC_APB1ENR |= (1u << 1) | (1u << 2); /* TIM3, TIM4 */
    (void)RCC_APB1ENR;
    pwm_timer_init(TIM3_BASE, APB1_TIMER_HZ / 1000000u, BOARD_SERVO_PERIOD_US, 1500u);
    pwm_timer_init(TIM4_BASE, 1u, HBRIDGE_PERIOD_TICKS, 0u);
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

void hal_eeprom_write(uint16_t addr, const void *src, uint16_t len)
{
    eeprom_ready();
    (void)fe_write(&s_eeprom, addr, src, len);
}

/* At rest: move to the other sector once the active one is half full, so the erase's stall falls
 * here and not while driving (a full sector while driving still moves, correctness first). */
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

/* RCC_CSR reset flags (RM0090 6.3.21), read once and cleared (RMVF) on the first call, which
 * main makes at boot. Every reset drives NRST, so PINRSTF alone means the pin; POR sets BORRSTF
 * too. QEMU does not model the RCC (reads 0): taken as a power-on. */
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

/* ---- init --------------------------------------------------------------- */
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
    gpio_clocks_on();
    actuators_init();
    __asm__ volatile("cpsie i");
}

#endif /* __arm__ */
