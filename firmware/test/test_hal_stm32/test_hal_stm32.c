/*
 * The STM32F405 HAL backend on QEMU netduinoplus2 (stm32f405 env only: the other envs list
 * this suite in test_ignore). Unit-test builds link the sim backend as "the HAL", so the real
 * backend is compiled into this file under other names (stm32_hal_*) and the two coexist.
 *
 * What QEMU 7.2 models, and so what is read back from the chip here: SysTick, NVIC, SYSCFG_EXTICR,
 * the EXTI registers, USART1 (BRR kept), TIM2..TIM5 registers (CR1, SMCR, CCMR1, CCER, PSC, ARR
 * kept). Not modelled: GPIO, RCC, FLASH, IWDG, TIM1 and TIM8..TIM14 (reads 0, writes ignored), and
 * EXTI_SWIER only stores its value (no pending bit, no interrupt), so a software edge is a SWIER
 * write plus the vector pended through NVIC_STIR. This suite points the backend's GPIO block at
 * RAM for the whole program (so the pin settings it writes are read back, and a test sets the
 * input levels it samples), and its RCC block at RAM for the crystal test only. What only a
 * board can show: docs/stm32.md.
 */
#include <stdint.h>

#include "../../lib/hal/stm32/board.h"

/* GPIOA..GPIOD: 0x400 bytes each, in RAM */
static volatile uint32_t s_gpio_ram[BOARD_PORT_COUNT][0x400u / 4u];
#define HAL_STM32_GPIO_BASE ((uint32_t)(uintptr_t)&s_gpio_ram[0][0])
/* the RCC: the chip's (QEMU: unmodelled, reads 0), or s_rcc_ram for one test */
#define RCC_CHIP_BASE 0x40023800u
static volatile uint32_t s_rcc_ram[0x80u / 4u];
static uint32_t s_rcc_base = RCC_CHIP_BASE;
#define HAL_STM32_RCC_BASE s_rcc_base

#define AGNAV_HAL_STM32_UNDER_TEST 1
#define hal_init stm32_hal_init
#define hal_clock_from_crystal stm32_hal_clock_from_crystal
#define hal_time_us stm32_hal_time_us
#define hal_time_ms stm32_hal_time_ms
#define hal_delay_us stm32_hal_delay_us
#define hal_idle_until stm32_hal_idle_until
#define hal_irq_save stm32_hal_irq_save
#define hal_irq_restore stm32_hal_irq_restore
#define hal_uart_init stm32_hal_uart_init
#define hal_uart_write stm32_hal_uart_write
#define hal_uart_read stm32_hal_uart_read
#define hal_uart_tx_space stm32_hal_uart_tx_space
#define hal_encoder_attach stm32_hal_encoder_attach
#define hal_encoder_poll stm32_hal_encoder_poll
#define hal_sonar_attach stm32_hal_sonar_attach
#define hal_sonar_trigger stm32_hal_sonar_trigger
#define hal_sonar_poll stm32_hal_sonar_poll
#define hal_servo_write_us stm32_hal_servo_write_us
#define hal_pwm_write_duty stm32_hal_pwm_write_duty
#define hal_eeprom_size stm32_hal_eeprom_size
#define hal_eeprom_read stm32_hal_eeprom_read
#define hal_eeprom_write_byte stm32_hal_eeprom_write_byte
#define hal_eeprom_busy stm32_hal_eeprom_busy
#define hal_eeprom_idle stm32_hal_eeprom_idle
#define hal_watchdog_start stm32_hal_watchdog_start
#define hal_watchdog_kick stm32_hal_watchdog_kick
#define hal_reset_cause stm32_hal_reset_cause
#include "../../lib/hal/stm32/hal_stm32.c"

#include <stdio.h>
#include <unity.h>

#include "encoder_isr.h"
#include "sonar_ring.h"

#define NVIC_STIR REG32(0xE000EF00u)
#define NVIC_ISER0 REG32(0xE000E100u)
#define NVIC_ISER1 REG32(0xE000E104u)

#define MAX_CALLS 16u
static volatile uint8_t s_calls;
static volatile uint8_t s_idx[MAX_CALLS], s_level[MAX_CALLS];
static volatile uint32_t s_t[MAX_CALLS];

static void record(uint8_t idx, uint8_t level, uint32_t t_us)
{
    if (s_calls < MAX_CALLS) {
        s_idx[s_calls] = idx;
        s_level[s_calls] = level;
        s_t[s_calls] = t_us;
    }
    s_calls++;
}

static void on_encoder(uint8_t idx, uint8_t ab, uint32_t t_us) { record(idx, ab, t_us); }
static void on_echo(uint8_t idx, uint8_t level, uint32_t t_us) { record(idx, level, t_us); }

static uint32_t irq_of_line(uint8_t line)
{
    return line <= 4u ? IRQ_EXTI0 + line : line <= 9u ? IRQ_EXTI9_5 : IRQ_EXTI15_10;
}

/* An edge on EXTI line `line` from software: SWIER (on silicon this alone pends the vector)
 * and NVIC_STIR (QEMU needs it). */
static void soft_edge(uint8_t line)
{
    EXTI_SWIER |= 1u << line;
    NVIC_STIR = irq_of_line(line);
    __asm__ volatile("dsb\n isb" ::: "memory");
}

/* The level a pin's input reads (GPIOx_IDR, RAM here). */
static void pin_level(uint8_t pin, bool high)
{
    volatile uint32_t *idr = &s_gpio_ram[BOARD_PIN_PORT(pin)][0x10u / 4u];
    uint32_t bit = 1u << BOARD_PIN_NUM(pin);
    *idr = high ? (*idr | bit) : (*idr & ~bit);
}

static uint32_t pin_mode(uint8_t pin) { return (s_gpio_ram[BOARD_PIN_PORT(pin)][0] >> (2u * BOARD_PIN_NUM(pin))) & 3u; }
static uint32_t pin_pull(uint8_t pin) { return (s_gpio_ram[BOARD_PIN_PORT(pin)][3] >> (2u * BOARD_PIN_NUM(pin))) & 3u; }
static uint32_t pin_af(uint8_t pin)
{
    uint8_t n = BOARD_PIN_NUM(pin);
    return (s_gpio_ram[BOARD_PIN_PORT(pin)][8u + (n >> 3)] >> (4u * (n & 7u))) & 0xFu;
}
static volatile uint32_t *port_bsrr(uint8_t pin) { return &s_gpio_ram[BOARD_PIN_PORT(pin)][0x18u / 4u]; }

/* The clock the firmware set up, from what it wrote to RCC_PLLCFGR (RM0090 7.3.2): the source
 * (PLLSRC: HSE or HSI) / PLLM * PLLN / PLLP. */
static uint32_t sysclk_from_pllcfgr(uint32_t cfg)
{
    uint32_t src = (cfg & (1u << 22)) != 0u ? BOARD_HSE_HZ : 16000000u;
    uint32_t m = cfg & 0x3Fu, n = (cfg >> 6) & 0x1FFu, p = 2u * (((cfg >> 16) & 3u) + 1u);
    return m == 0u ? 0u : (uint32_t)((uint64_t)src / m * n / p);
}

static void systick_1khz(void)
{
    SYST_CSR = 0u;
    SYST_RVR = SYSTICK_RELOAD - 1u;
    SYST_CVR = 0u;
    SYST_CSR = 7u;
}

void setUp(void)
{
    s_calls = 0;
    EXTI_SWIER = 0u; /* QEMU keeps software edges a test left unserviced */
    stm32_hal_encoder_attach(0u, 0u, 0);
    stm32_hal_sonar_attach(0u, 0);
}

void tearDown(void) {}

/* ---- time ---------------------------------------------------------------- */

/* One masked SysTick wrap, read twice inside the mask and once after the handler ran. Returns
 * NULL when the reads are consistent, else what went wrong. */
static const char *masked_wrap_once(void)
{
    hal_irq_state_t s = hal_irq_save();
    uint32_t before = hal_time_us();
    uint32_t prev = SYST_CVR;
    for (uint32_t i = 0; i < 2000000u; i++) { /* until the counter reloads (a wrap) */
        uint32_t now = SYST_CVR;
        if (now > prev) {
            break;
        }
        prev = now;
    }
    uint32_t first = hal_time_us();  /* sees COUNTFLAG */
    uint32_t second = hal_time_us(); /* COUNTFLAG already read: must see the pending SysTick */
    hal_irq_restore(s);               /* the handler counts the wrap now */
    uint32_t after = hal_time_us();
    if ((int32_t)(first - before) <= 0) return "time did not move on over the wrap";
    if ((int32_t)(second - first) < 0) return "second read inside the mask went back";
    if ((int32_t)(after - second) < 0) return "went back after the handler ran";
    if ((int32_t)(after - second) >= 900) return "the wrap was counted twice";
    return NULL;
}

static void test_time_us_counts_a_masked_wrap_once(void)
{
    /* QEMU's virtual clock runs on while the host deschedules it, so a loaded machine can put
     * a 1 ms gap between two reads of one attempt; a double count shows in every attempt. */
    const char *why = NULL;
    for (uint8_t attempt = 0; attempt < 3u; attempt++) {
        why = masked_wrap_once();
        if (why == NULL) {
            break;
        }
    }
    TEST_ASSERT_NULL_MESSAGE(why, why);
}

static void test_time_us_is_monotonic_and_matches_ms(void)
{
    uint32_t t0 = hal_time_us();
    uint32_t prev = t0;
    while ((uint32_t)(prev - t0) < 5000u) {
        uint32_t now = hal_time_us();
        TEST_ASSERT_TRUE((int32_t)(now - prev) >= 0);
        prev = now;
    }
    uint32_t ms = hal_time_ms();
    uint32_t us = hal_time_us();
    TEST_ASSERT_UINT32_WITHIN(1000u, ms * 1000u + 500u, us);
}

static void test_delay_us_waits_at_least_the_time(void)
{
    uint32_t t0 = hal_time_us();
    hal_delay_us(10u);
    uint32_t dt = hal_time_us() - t0;
    TEST_ASSERT_TRUE(dt >= 10u);
    t0 = hal_time_us();
    hal_sonar_trigger(3u); /* 10 us trigger pulse */
    dt = hal_time_us() - t0;
    TEST_ASSERT_TRUE(dt >= BOARD_SONAR_TRIGGER_US);
}

/* ---- clock --------------------------------------------------------------- */

/* QEMU's RCC reads 0: HSERDY never comes, so the boot took the HSI path, and says so. */
static void test_clock_falls_back_to_hsi_pll_when_the_crystal_does_not_start(void)
{
    TEST_ASSERT_FALSE_MESSAGE(hal_clock_from_crystal(), "no HSERDY: the fallback must be reported");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, s_pllcfgr & (1u << 22), "PLL source HSI");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(8u, s_pllcfgr & 0x3Fu, "PLLM: 16 MHz / 8 = 2 MHz reference");
    TEST_ASSERT_EQUAL_UINT32(168000000u, sysclk_from_pllcfgr(s_pllcfgr));
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(48000000u, 2000000u * ((s_pllcfgr >> 6) & 0x1FFu) / ((s_pllcfgr >> 24) & 0xFu),
                                     "PLLQ: 48 MHz for USB");
}

/* With RCC in RAM: a crystal that starts (HSERDY set) and one that does not. */
static void test_clock_uses_the_crystal_when_it_starts_and_switches_it_off_when_not(void)
{
    for (uint32_t i = 0; i < sizeof s_rcc_ram / 4u; i++) {
        s_rcc_ram[i] = 0u;
    }
    s_rcc_ram[0] = RCC_CR_HSERDY | RCC_CR_PLLRDY; /* the oscillator and the PLL answer at once */
    s_rcc_ram[1] = 0x24003010u;                  /* RCC_PLLCFGR reset value: reserved bit 29 set */
    s_rcc_ram[2] = RCC_CFGR_SWS_PLL;
    s_rcc_base = (uint32_t)(uintptr_t)&s_rcc_ram[0];
    clock_init();
    bool hse = hal_clock_from_crystal();
    uint32_t cr = s_rcc_ram[0], pll = s_rcc_ram[1], cfgr = s_rcc_ram[2];

    s_rcc_ram[0] = 0u; /* a crystal that never starts */
    clock_init();
    bool hsi_hse = hal_clock_from_crystal();
    uint32_t cr_fail = s_rcc_ram[0], pll_fail = s_rcc_ram[1];
    s_rcc_base = RCC_CHIP_BASE;
    clock_init(); /* back to what the chip (QEMU) gives */
    systick_1khz();

    TEST_ASSERT_TRUE_MESSAGE(hse, "HSERDY: from the crystal");
    TEST_ASSERT_TRUE_MESSAGE(cr & RCC_CR_HSEON, "HSE on");
    TEST_ASSERT_TRUE_MESSAGE(cr & RCC_CR_PLLON, "PLL on");
    TEST_ASSERT_TRUE_MESSAGE(cr & RCC_CR_CSSON, "clock security system on with the crystal");
    TEST_ASSERT_TRUE_MESSAGE(pll & (1u << 22), "PLL source HSE");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(4u, pll & 0x3Fu, "PLLM: 8 MHz / 4 = 2 MHz");
    TEST_ASSERT_EQUAL_UINT32(168u, (pll >> 6) & 0x1FFu);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0u, (pll >> 16) & 3u, "PLLP = /2");
    TEST_ASSERT_EQUAL_UINT32(7u, (pll >> 24) & 0xFu);
    TEST_ASSERT_TRUE_MESSAGE(pll & (1u << 29), "reserved bit kept at its reset value");
    TEST_ASSERT_EQUAL_UINT32(168000000u, sysclk_from_pllcfgr(pll));
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(2u, cfgr & 3u, "SW = PLL");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, (cfgr >> 4) & 0xFu, "HPRE = /1");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(5u, (cfgr >> 10) & 7u, "PPRE1 = /4: APB1 42 MHz");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(4u, (cfgr >> 13) & 7u, "PPRE2 = /2: APB2 84 MHz");

    TEST_ASSERT_FALSE_MESSAGE(hsi_hse, "no HSERDY: from the HSI");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, cr_fail & (RCC_CR_HSEON | RCC_CR_CSSON), "a dead crystal is switched off");
    TEST_ASSERT_EQUAL_HEX32(0u, pll_fail & (1u << 22));
    TEST_ASSERT_EQUAL_UINT32(168000000u, sysclk_from_pllcfgr(pll_fail));
    TEST_ASSERT_FALSE(hal_clock_from_crystal());
}

/* SysTick, the UART and the timers are set from the clock the PLL was given. */
static void test_systick_uart_and_timers_are_set_for_the_clock_in_use(void)
{
    uint32_t sysclk = sysclk_from_pllcfgr(s_pllcfgr);
    uint32_t apb1_timer = 2u * (sysclk / 4u), apb2 = sysclk / 2u, apb2_timer = 2u * apb2;
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(sysclk / 1000u - 1u, SYST_RVR, "SysTick 1 kHz");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(apb2, APB2_HZ, "USART1 divides APB2");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(1000000u, apb2_timer / SERVO_PRESCALER, "servo timer 1 MHz");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(20000u, apb2_timer / HBRIDGE_PERIOD_TICKS, "H-bridge 20 kHz");
    /* input filter clock f_DTS: 42 MHz on APB1 (CKD = 01) and APB2 (CKD = 10) encoder timers */
    TEST_ASSERT_EQUAL_UINT32(42000000u, apb1_timer >> 1);
    TEST_ASSERT_EQUAL_UINT32(42000000u, apb2_timer >> 2);
    stm32_hal_uart_init(HAL_UART_LINK, 57600u);
    TEST_ASSERT_UINT32_WITHIN(576u, 57600u, apb2 / USART1_BRR);
}

/* ---- link UART bit rate (USART1_BRR, modelled) ---------------------------- */

/* |actual - nominal| in ppm of nominal, 16x oversampling: actual = f_PCLK / BRR (RM0090 30.3.4). */
static uint32_t baud_error_ppm(uint32_t brr, uint32_t baud)
{
    uint64_t actual_x1000 = (uint64_t)APB2_HZ * 1000u / brr;
    uint64_t nominal_x1000 = (uint64_t)baud * 1000u;
    uint64_t off = actual_x1000 > nominal_x1000 ? actual_x1000 - nominal_x1000 : nominal_x1000 - actual_x1000;
    return (uint32_t)(off * 1000000u / nominal_x1000);
}

static void test_uart_brr_is_the_nearest_setting_and_within_1_percent(void)
{
    static const uint32_t BAUD[] = {9600u, 19200u, 38400u, 57600u, 115200u};
    char msg[48];
    for (uint8_t i = 0; i < sizeof BAUD / sizeof BAUD[0]; i++) {
        stm32_hal_uart_init(HAL_UART_LINK, BAUD[i]);
        uint32_t brr = USART1_BRR & 0xFFFFu;
        snprintf(msg, sizeof msg, "%lu baud: BRR %lu", (unsigned long)BAUD[i], (unsigned long)brr);
        TEST_ASSERT_TRUE_MESSAGE(brr >= 16u, msg);
        TEST_ASSERT_TRUE_MESSAGE(baud_error_ppm(brr, BAUD[i]) <= 10000u, msg);
    }
    /* every rate up to 230400, where truncating f / baud (364) is off by one sixteenth */
    static const uint32_t NEAREST[] = {9600u, 19200u, 38400u, 57600u, 115200u, 230400u};
    for (uint8_t i = 0; i < sizeof NEAREST / sizeof NEAREST[0]; i++) {
        stm32_hal_uart_init(HAL_UART_LINK, NEAREST[i]);
        uint32_t brr = USART1_BRR & 0xFFFFu;
        snprintf(msg, sizeof msg, "%lu baud: BRR %lu not nearest", (unsigned long)NEAREST[i], (unsigned long)brr);
        TEST_ASSERT_TRUE_MESSAGE(baud_error_ppm(brr, NEAREST[i]) <= baud_error_ppm(brr + 1u, NEAREST[i]), msg);
        TEST_ASSERT_TRUE_MESSAGE(baud_error_ppm(brr, NEAREST[i]) <= baud_error_ppm(brr - 1u, NEAREST[i]), msg);
    }
    stm32_hal_uart_init(HAL_UART_LINK, 57600u);
}

/* ---- encoders -------------------------------------------------------------- */

static void test_quadrature_encoders_use_the_timers_encoder_mode(void)
{
    stm32_hal_encoder_attach(4u, 0u, on_encoder);
    static const uint32_t MODELLED[] = {BOARD_TIM2_BASE, BOARD_TIM3_BASE, BOARD_TIM4_BASE}; /* TIM8: not in QEMU */
    for (uint8_t k = 0; k < 3u; k++) {
        uint32_t b = MODELLED[k];
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(TIM_CR1_CEN | TIM_CR1_CKD(1u), TIM_REG(b, TIM_CR1) & 0x3FFu,
                                        "counting, f_DTS = CK_INT / 2");
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(3u, TIM_REG(b, TIM_SMCR) & 7u, "SMS = 011: x4 on TI1 and TI2");
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(0xC1C1u, TIM_REG(b, TIM_CCMR1) & 0xFFFFu, "CC1S/CC2S = TI1/TI2, IC1F/IC2F = 1100");
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, TIM_REG(b, TIM_CCER) & 0xAAu, "inputs not inverted");
        TEST_ASSERT_EQUAL_HEX32(0xFFFFu, TIM_REG(b, TIM_ARR));
        TEST_ASSERT_EQUAL_UINT32(0u, TIM_REG(b, TIM_PSC));
    }
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(GPIO_MODE_AF, pin_mode(s_enc_a_pin[i]), "A: timer input");
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_AF, pin_mode(s_enc_b_pin[i]));
        TEST_ASSERT_EQUAL_UINT32(s_enc_af[i], pin_af(s_enc_a_pin[i]));
        TEST_ASSERT_EQUAL_UINT32(s_enc_af[i], pin_af(s_enc_b_pin[i]));
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(GPIO_PULL_UP, pin_pull(s_enc_a_pin[i]), "open-collector outputs");
        TEST_ASSERT_EQUAL_UINT32(GPIO_PULL_UP, pin_pull(s_enc_b_pin[i]));
    }
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, EXTI_IMR & BOARD_HALL_LINES_MASK, "no interrupt per edge");
    stm32_hal_encoder_attach(0u, 0u, 0);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, TIM_REG(BOARD_TIM3_BASE, TIM_CR1) & TIM_CR1_CEN, "detached: stopped");
}

static void test_hall_encoders_use_exti_on_their_a_pins_and_stop_the_timers(void)
{
    stm32_hal_encoder_attach(4u, 0x0Fu, on_encoder);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0x0u, (SYSCFG_EXTICR(0) >> 4) & 0xFu, "line 1 <- PA1");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0x2110u, SYSCFG_EXTICR(1) & 0xFFF0u, "lines 5, 6, 7 <- PB5, PB6, PC7");
    TEST_ASSERT_EQUAL_HEX32(BOARD_HALL_LINES_MASK, EXTI_IMR & BOARD_HALL_LINES_MASK);
    TEST_ASSERT_EQUAL_HEX32(BOARD_HALL_LINES_MASK, EXTI_RTSR & BOARD_HALL_LINES_MASK);
    TEST_ASSERT_EQUAL_HEX32(BOARD_HALL_LINES_MASK, EXTI_FTSR & BOARD_HALL_LINES_MASK);
    TEST_ASSERT_TRUE(NVIC_ISER0 & (1u << (IRQ_EXTI0 + 1u)));
    TEST_ASSERT_TRUE(NVIC_ISER0 & (1u << IRQ_EXTI9_5));
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_IN, pin_mode(s_enc_a_pin[i]));
        TEST_ASSERT_EQUAL_UINT32(GPIO_PULL_UP, pin_pull(s_enc_a_pin[i]));
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(GPIO_PULL_DOWN, pin_pull(s_enc_b_pin[i]), "B unused: not pulled up");
    }
    TEST_ASSERT_EQUAL_HEX32(0u, TIM_REG(BOARD_TIM2_BASE, TIM_CR1) & TIM_CR1_CEN);
    TEST_ASSERT_EQUAL_HEX32(0u, TIM_REG(BOARD_TIM4_BASE, TIM_CR1) & TIM_CR1_CEN);
    stm32_hal_encoder_attach(2u, 0x01u, on_encoder); /* wheel 0 Hall, wheel 1 on TIM3 */
    TEST_ASSERT_EQUAL_HEX32(1u << 1, EXTI_IMR & BOARD_HALL_LINES_MASK);
    TEST_ASSERT_TRUE(TIM_REG(BOARD_TIM3_BASE, TIM_CR1) & TIM_CR1_CEN);
}

/* A Hall wheel's edge: ab = (A << 1), B = 0 whatever its pin reads (hal.h). */
static void test_hall_edge_calls_hook_with_a_and_b_as_0(void)
{
    stm32_hal_encoder_attach(4u, 0x0Fu, on_encoder);
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        pin_level(s_enc_b_pin[i], true); /* a B line that reads high */
    }
    uint32_t t_before = hal_time_us();
    pin_level(s_enc_a_pin[2], true);
    soft_edge(BOARD_PIN_NUM(s_enc_a_pin[2]));
    pin_level(s_enc_a_pin[2], false);
    hal_delay_us(20u);
    soft_edge(BOARD_PIN_NUM(s_enc_a_pin[2]));
    pin_level(s_enc_a_pin[0], true);
    soft_edge(BOARD_PIN_NUM(s_enc_a_pin[0]));
    TEST_ASSERT_EQUAL_UINT8(3u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(2u, s_idx[0]);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(2u, s_level[0], "A high, B 0");
    TEST_ASSERT_EQUAL_UINT8(2u, s_idx[1]);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, s_level[1], "A low, B 0");
    TEST_ASSERT_EQUAL_UINT8(0u, s_idx[2]);
    TEST_ASSERT_EQUAL_HEX8(2u, s_level[2]);
    TEST_ASSERT_TRUE((int32_t)(s_t[0] - t_before) >= 0);
    TEST_ASSERT_TRUE_MESSAGE((int32_t)(s_t[1] - s_t[0]) >= 20, "timestamps");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, EXTI_SWIER & BOARD_HALL_LINES_MASK, "software edges consumed");
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        pin_level(s_enc_a_pin[i], false);
        pin_level(s_enc_b_pin[i], false);
    }
    stm32_hal_encoder_attach(2u, 0x01u, on_encoder); /* wheel 1 timer-counted: its A line is no hook's */
    s_calls = 0;
    soft_edge(BOARD_PIN_NUM(s_enc_a_pin[1]));
    soft_edge(BOARD_PIN_NUM(s_enc_a_pin[3]));
    TEST_ASSERT_EQUAL_UINT8(0u, s_calls);
    EXTI_SWIER = 0u;
}

/* The fold from a timer count to the interrupt record (encoder_isr.h): forward when A leads B,
 * on either channel, across the 16-bit wrap, stamped with the poll time. */
static void test_encoder_count_folds_into_the_record_as_steps(void)
{
    memset(encoder_isr_state, 0, sizeof encoder_isr_state);
    memset(s_enc_cnt, 0, sizeof s_enc_cnt);
    /* encoder 2: A = TIM4 CH1 (TI1): the counter goes up when A leads */
    encoder_fold_count(2u, 5u, 4000u);
    TEST_ASSERT_EQUAL_UINT16(5u, encoder_isr_state[2].fwd);
    TEST_ASSERT_EQUAL_UINT16(1000u, encoder_isr_state[2].fwd_stamp); /* t_us >> 2 */
    encoder_fold_count(2u, 3u, 4400u);
    TEST_ASSERT_EQUAL_UINT16(5u, encoder_isr_state[2].fwd);
    TEST_ASSERT_EQUAL_UINT16(2u, encoder_isr_state[2].back);
    TEST_ASSERT_EQUAL_UINT16(1100u, encoder_isr_state[2].back_stamp);
    encoder_fold_count(2u, 0xFFF0u, 4800u); /* 3 -> 0xFFF0: 19 back across the wrap */
    TEST_ASSERT_EQUAL_UINT16(21u, encoder_isr_state[2].back);
    encoder_fold_count(2u, 0x0010u, 5200u); /* and 32 forward */
    TEST_ASSERT_EQUAL_UINT16(37u, encoder_isr_state[2].fwd);
    encoder_fold_count(2u, 0x0010u, 5600u); /* no step: no stamp */
    TEST_ASSERT_EQUAL_UINT16(1300u, encoder_isr_state[2].fwd_stamp);
    /* encoder 0: A = TIM2 CH2 (TI2): the counter goes up when B leads */
    encoder_fold_count(0u, 7u, 8000u);
    TEST_ASSERT_EQUAL_UINT16(0u, encoder_isr_state[0].fwd);
    TEST_ASSERT_EQUAL_UINT16(7u, encoder_isr_state[0].back);
    encoder_fold_count(0u, 0u, 8000u);
    TEST_ASSERT_EQUAL_UINT16(7u, encoder_isr_state[0].fwd);
    TEST_ASSERT_EQUAL_UINT16(0u, encoder_isr_state[1].fwd + encoder_isr_state[1].back + encoder_isr_state[3].fwd);
    TEST_ASSERT_EQUAL_UINT16(0u, encoder_isr_state[2].errors);
}

/* hal_encoder_poll() reads the counter of each timer-counted wheel, and only those. QEMU's timer
 * model counts CNT up on its own clock whatever SMCR and ARR say (reads pass 0xFFFF), so the count
 * moves between any two reads: what the poll folds is the step from the count at attach to the
 * one it read. */
static void test_encoder_poll_folds_the_timer_counters(void)
{
    stm32_hal_encoder_attach(3u, 0x02u, on_encoder); /* wheels 0 and 2 on TIM2 / TIM4, 1 Hall */
    memset(encoder_isr_state, 0, sizeof encoder_isr_state);
    uint16_t prev0 = s_enc_cnt[0], prev2 = s_enc_cnt[2];
    stm32_hal_encoder_poll();
    TEST_ASSERT_NOT_EQUAL_MESSAGE(prev0, s_enc_cnt[0], "the poll read TIM2_CNT");
    TEST_ASSERT_NOT_EQUAL_MESSAGE(prev2, s_enc_cnt[2], "the poll read TIM4_CNT");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE((uint16_t)(s_enc_cnt[0] - prev0),
                                     (uint16_t)(encoder_isr_state[0].back - encoder_isr_state[0].fwd),
                                     "wheel 0 (A on TI2): the counter's step, as raw-backward");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE((uint16_t)(s_enc_cnt[2] - prev2),
                                     (uint16_t)(encoder_isr_state[2].fwd - encoder_isr_state[2].back),
                                     "wheel 2 (A on TI1): the counter's step, as raw-forward");
    TEST_ASSERT_TRUE_MESSAGE(encoder_isr_state[0].fwd + encoder_isr_state[0].back != 0u, "a step was folded");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, encoder_isr_state[1].fwd + encoder_isr_state[1].back,
                                     "the Hall wheel's record is the hook's");
}

/* ---- sonars: one EXTI line per echo, shared triggers ----------------------- */

static void test_sonar_attach_gives_each_echo_its_own_line_on_both_edges(void)
{
    stm32_hal_sonar_attach(12u, on_echo);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0x2301u, SYSCFG_EXTICR(0) & 0xFF0Fu, "lines 0, 2, 3 <- PB0, PD2, PC3");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0x0u, SYSCFG_EXTICR(1) & 0xFu, "line 4 <- PA4");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0x1122u, SYSCFG_EXTICR(2) & 0xFFFFu, "lines 8..11 <- PC8, PC9, PB10, PB11");
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0x1111u, SYSCFG_EXTICR(3) & 0xFFFFu, "lines 12..15 <- PB12..PB15");
    TEST_ASSERT_EQUAL_HEX32(BOARD_ECHO_LINES_MASK, EXTI_IMR & BOARD_ECHO_LINES_MASK);
    TEST_ASSERT_EQUAL_HEX32(BOARD_ECHO_LINES_MASK, EXTI_RTSR & BOARD_ECHO_LINES_MASK);
    TEST_ASSERT_EQUAL_HEX32(BOARD_ECHO_LINES_MASK, EXTI_FTSR & BOARD_ECHO_LINES_MASK);
    TEST_ASSERT_TRUE(NVIC_ISER1 & (1u << (IRQ_EXTI15_10 - 32u)));
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_IN, pin_mode(s_echo_pin[i]));
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(GPIO_PULL_DOWN, pin_pull(s_echo_pin[i]), "an empty socket reads 0");
    }
    for (uint8_t t = 0; t < BOARD_SONAR_TRIGGER_COUNT; t++) {
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_OUT, pin_mode(s_trigger_pin[t]));
    }
    stm32_hal_sonar_attach(3u, on_echo);
    TEST_ASSERT_EQUAL_HEX32(0x7000u, EXTI_IMR & BOARD_ECHO_LINES_MASK); /* PB12..PB14 only */
}

static void test_echo_edge_on_each_line_calls_hook_with_its_sonar_and_level(void)
{
    stm32_hal_sonar_attach(12u, on_echo);
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        pin_level(s_echo_pin[i], (i & 1u) != 0u);
    }
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        soft_edge(BOARD_PIN_NUM(s_echo_pin[i]));
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(i + 1u, s_calls, "one call per edge");
        TEST_ASSERT_EQUAL_UINT8(i, s_idx[i]);
        TEST_ASSERT_EQUAL_UINT8(i & 1u, s_level[i]);
    }
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        pin_level(s_echo_pin[i], false);
    }
    TEST_ASSERT_EQUAL_HEX32(0u, EXTI_SWIER & BOARD_ECHO_LINES_MASK);
}

static void test_echo_edge_of_a_sonar_beyond_count_is_ignored(void)
{
    stm32_hal_sonar_attach(2u, on_echo);
    soft_edge(14u); /* sonar 2 */
    soft_edge(9u);  /* sonar 6 */
    TEST_ASSERT_EQUAL_UINT8(0u, s_calls);
    soft_edge(13u); /* sonar 1 */
    TEST_ASSERT_EQUAL_UINT8(1u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(1u, s_idx[0]);
    EXTI_SWIER = 0u;
}

/* Sonars 1, 4, 7, 10 share PA8: the first trigger of a group firing pulses it, the others
 * within BOARD_SONAR_TRIGGER_SHARED_US do not; own pins pulse every time. */
static void test_shared_trigger_pin_pulses_once_per_group_firing(void)
{
    stm32_hal_sonar_attach(12u, on_echo);
    volatile uint32_t *bsrr_a = port_bsrr(BOARD_PA(8));
    volatile uint32_t *bsrr_c = port_bsrr(BOARD_PC(0));
    *bsrr_a = 0u;
    hal_sonar_trigger(1u);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(1u << (8u + 16u), *bsrr_a, "PA8 pulsed (last write: low again)");
    *bsrr_a = 0u;
    hal_sonar_trigger(4u);
    hal_sonar_trigger(7u);
    hal_sonar_trigger(10u);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, *bsrr_a, "4, 7, 10 fired with 1's pulse: PA8 not written");
    *bsrr_c = 0u;
    hal_sonar_trigger(0u);
    TEST_ASSERT_EQUAL_HEX32(1u << 16, *bsrr_c);
    *bsrr_c = 0u;
    hal_sonar_trigger(0u); /* an own pin: pulsed again */
    TEST_ASSERT_EQUAL_HEX32(1u << 16, *bsrr_c);
    hal_delay_us(BOARD_SONAR_TRIGGER_SHARED_US);
    hal_sonar_trigger(7u); /* the group's next firing */
    TEST_ASSERT_EQUAL_HEX32(1u << (8u + 16u), *bsrr_a);
}

/* Every sonar that shares a trigger pin must be in the same group as its sharers, for every ring
 * size, against the ring's own schedule. */
static void test_sonars_sharing_a_trigger_are_always_in_the_same_group(void)
{
    for (uint8_t n = 1; n <= SONAR_RING_MAX; n++) {
        sonar_ring_cfg_t cfg = {SONAR_RING_12_SDLG.sensor, n};
        TEST_ASSERT_TRUE(sonar_ring_init(&cfg)); /* attaches to the sim HAL: harmless */
        for (uint8_t i = 0; i < n; i++) {
            for (uint8_t j = (uint8_t)(i + 1u); j < n; j++) {
                if (s_trigger_of[i] == s_trigger_of[j]) {
                    TEST_ASSERT_EQUAL_MESSAGE(sonar_ring_group_of(i), sonar_ring_group_of(j),
                                              "trigger sharers in different groups");
                }
            }
        }
    }
}

/* ---- the pin map ------------------------------------------------------------ */

static void test_pin_map_uses_each_pin_once_and_keeps_the_boards_pins_free(void)
{
    uint8_t used[BOARD_PORT_COUNT * 16u + 16u] = {0};
    const uint8_t reserved[] = BOARD_RESERVED_PINS;
    for (uint8_t i = 0; i < sizeof reserved; i++) {
        used[reserved[i]]++;
    }
    used[BOARD_UART_TX_PIN]++;
    used[BOARD_UART_RX_PIN]++;
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        used[s_enc_a_pin[i]]++;
        used[s_enc_b_pin[i]]++;
    }
    for (uint8_t i = 0; i < HAL_SERVO_MAX; i++) {
        used[s_servo_pin[i]]++;
    }
    for (uint8_t i = 0; i < HAL_PWM_MAX; i++) {
        used[s_hbridge_pwm_pin[i]]++;
        used[s_hbridge_dir_pin[i]]++;
    }
    for (uint8_t t = 0; t < BOARD_SONAR_TRIGGER_COUNT; t++) {
        used[s_trigger_pin[t]]++;
    }
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        used[s_echo_pin[i]]++;
        TEST_ASSERT_TRUE(s_trigger_of[i] < BOARD_SONAR_TRIGGER_COUNT);
    }
    for (uint16_t p = 0; p < sizeof used; p++) {
        TEST_ASSERT_TRUE_MESSAGE(used[p] <= 1u, "pin used twice, or a board pin used");
    }
    /* the 16 EXTI lines: each echo and each Hall A line its own */
    uint32_t echo = 0u, hall = 0u;
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, echo & (1u << BOARD_PIN_NUM(s_echo_pin[i])), "two echoes on a line");
        echo |= 1u << BOARD_PIN_NUM(s_echo_pin[i]);
    }
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        TEST_ASSERT_EQUAL_HEX32(0u, hall & (1u << BOARD_PIN_NUM(s_enc_a_pin[i])));
        hall |= 1u << BOARD_PIN_NUM(s_enc_a_pin[i]);
    }
    TEST_ASSERT_EQUAL_HEX32(BOARD_ECHO_LINES_MASK, echo);
    TEST_ASSERT_EQUAL_HEX32(BOARD_HALL_LINES_MASK, hall);
    TEST_ASSERT_EQUAL_HEX32(0u, echo & hall);
}

/* Encoder mode exists on TIM1..5 and TIM8 only (RM0090: TIM9..14 have no encoder interface);
 * the actuators use none of those. */
static void test_encoders_have_timers_with_encoder_mode_and_actuators_others(void)
{
    static const uint32_t ENCODER_MODE[] = {0x40010000u, BOARD_TIM2_BASE, BOARD_TIM3_BASE, BOARD_TIM4_BASE,
                                            0x40000C00u, BOARD_TIM8_BASE};
    for (uint8_t i = 0; i < HAL_ENCODER_MAX; i++) {
        bool ok = false;
        for (uint8_t k = 0; k < 6u; k++) {
            ok = ok || s_enc_timer[i] == ENCODER_MODE[k];
        }
        TEST_ASSERT_TRUE_MESSAGE(ok, "encoder on a timer without encoder mode");
        for (uint8_t j = (uint8_t)(i + 1u); j < HAL_ENCODER_MAX; j++) {
            TEST_ASSERT_NOT_EQUAL(s_enc_timer[i], s_enc_timer[j]);
        }
        for (uint8_t k = 0; k < HAL_PWM_MAX; k++) {
            TEST_ASSERT_NOT_EQUAL(s_enc_timer[i], s_hbridge_timer[k]);
        }
        TEST_ASSERT_NOT_EQUAL(s_enc_timer[i], SERVO_TIMER);
    }
    TEST_ASSERT_TRUE(SERVO_TIMER >= BOARD_TIM9_BASE && s_hbridge_timer[0] >= BOARD_TIM9_BASE &&
                     s_hbridge_timer[1] >= BOARD_TIM9_BASE);
}

/* ---- actuators (TIM9..11 are not modelled: the values written, and the pins) ---- */

static void test_servo_pulse_is_clamped_and_its_pins_are_tim9(void)
{
    TEST_ASSERT_EQUAL_UINT32(1000u, servo_ccr(1000u));
    TEST_ASSERT_EQUAL_UINT32(2000u, servo_ccr(2000u));
    TEST_ASSERT_EQUAL_UINT32(2200u, servo_ccr(5000u));
    TEST_ASSERT_EQUAL_UINT32(800u, servo_ccr(0u));
    TEST_ASSERT_EQUAL_UINT32(BOARD_SERVO_PERIOD_US, 20000u);
    for (uint8_t i = 0; i < HAL_SERVO_MAX; i++) {
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_AF, pin_mode(s_servo_pin[i]));
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(3u, pin_af(s_servo_pin[i]), "AF3: TIM9");
    }
}

static void test_hbridge_duty_scales_8_bits_to_the_20_khz_period_and_sets_dir(void)
{
    TEST_ASSERT_EQUAL_UINT32(8400u, HBRIDGE_PERIOD_TICKS);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(HBRIDGE_PERIOD_TICKS, hbridge_ccr(255u), "255: always on (CCR = ARR + 1)");
    TEST_ASSERT_EQUAL_UINT32(128u * 8400u / 255u, hbridge_ccr(128u));
    TEST_ASSERT_EQUAL_UINT32(0u, hbridge_ccr(0u));
    for (uint8_t i = 0; i < HAL_PWM_MAX; i++) {
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_AF, pin_mode(s_hbridge_pwm_pin[i]));
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(3u, pin_af(s_hbridge_pwm_pin[i]), "AF3: TIM10 / TIM11");
        TEST_ASSERT_EQUAL_UINT32(GPIO_MODE_OUT, pin_mode(s_hbridge_dir_pin[i]));
    }
    volatile uint32_t *bsrr = port_bsrr(s_hbridge_dir_pin[1]);
    hal_pwm_write_duty(1u, 128u, true);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(1u << BOARD_PIN_NUM(s_hbridge_dir_pin[1]), *bsrr, "DIR high = reverse");
    hal_pwm_write_duty(1u, 128u, false);
    TEST_ASSERT_EQUAL_HEX32(1u << (BOARD_PIN_NUM(s_hbridge_dir_pin[1]) + 16u), *bsrr);
}

/* ---- watchdog and reset cause ---------------------------------------------- */

static void test_iwdg_setting_picks_the_finest_prescaler_for_the_timeout(void)
{
    uint32_t pr, rlr;
    iwdg_setting(250u, &pr, &rlr); /* 8000 LSI ticks: /4, 2000 */
    TEST_ASSERT_EQUAL_UINT32(0u, pr);
    TEST_ASSERT_EQUAL_UINT32(1999u, rlr);
    iwdg_setting(1000u, &pr, &rlr); /* 32000 ticks: /8, 4000 */
    TEST_ASSERT_EQUAL_UINT32(1u, pr);
    TEST_ASSERT_EQUAL_UINT32(3999u, rlr);
    iwdg_setting(32768u, &pr, &rlr); /* the longest: /256, 4096 */
    TEST_ASSERT_EQUAL_UINT32(6u, pr);
    TEST_ASSERT_EQUAL_UINT32(4095u, rlr);
    iwdg_setting(60000u, &pr, &rlr); /* saturates */
    TEST_ASSERT_EQUAL_UINT32(6u, pr);
    TEST_ASSERT_EQUAL_UINT32(4095u, rlr);
    iwdg_setting(0u, &pr, &rlr);
    TEST_ASSERT_EQUAL_UINT32(0u, pr);
    TEST_ASSERT_EQUAL_UINT32(0u, rlr);
    for (uint32_t ms = 1u; ms <= 32768u; ms = ms * 3u + 1u) { /* within one reload step */
        iwdg_setting((uint16_t)ms, &pr, &rlr);
        uint32_t got_ms_x1000 = (4u << pr) * (rlr + 1u) * 1000u / (LSI_HZ / 1000u);
        TEST_ASSERT_UINT32_WITHIN((4u << pr) * 1000u / (LSI_HZ / 1000u), ms * 1000u, got_ms_x1000);
    }
}

static void test_watchdog_start_and_kick_return(void)
{
    uint32_t t0 = hal_time_us();
    hal_watchdog_start(250u);
    hal_watchdog_kick();
    TEST_ASSERT_TRUE_MESSAGE(hal_time_us() - t0 < 10000u, "IWDG status wait is bounded");
    TEST_ASSERT_EQUAL(HAL_RESET_POWER_ON, hal_reset_cause()); /* QEMU: RCC_CSR reads 0 */
}

/* RCC_CSR flags at their RM0090 7.3.21 positions; every reset also sets PINRSTF (bit 26). */
static void test_reset_cause_reads_the_rcc_csr_flags(void)
{
    const uint32_t pin = 1u << 26;
    TEST_ASSERT_EQUAL(HAL_RESET_WATCHDOG, reset_cause_of((1u << 29) | pin)); /* IWDGRSTF */
    TEST_ASSERT_EQUAL(HAL_RESET_WATCHDOG, reset_cause_of((1u << 30) | pin)); /* WWDGRSTF */
    TEST_ASSERT_EQUAL(HAL_RESET_POWER_ON, reset_cause_of((1u << 27) | (1u << 25) | pin)); /* POR + BOR */
    TEST_ASSERT_EQUAL(HAL_RESET_BROWN_OUT, reset_cause_of((1u << 25) | pin));
    TEST_ASSERT_EQUAL(HAL_RESET_OTHER, reset_cause_of((1u << 28) | pin)); /* SFTRSTF */
    TEST_ASSERT_EQUAL(HAL_RESET_OTHER, reset_cause_of((1u << 31) | pin)); /* LPWRRSTF */
    TEST_ASSERT_EQUAL(HAL_RESET_EXTERNAL, reset_cause_of(pin));
    TEST_ASSERT_EQUAL(HAL_RESET_POWER_ON, reset_cause_of(0u));
}

int main(void)
{
    hal_init();
    UNITY_BEGIN();
    RUN_TEST(test_time_us_counts_a_masked_wrap_once);
    RUN_TEST(test_time_us_is_monotonic_and_matches_ms);
    RUN_TEST(test_delay_us_waits_at_least_the_time);
    RUN_TEST(test_clock_falls_back_to_hsi_pll_when_the_crystal_does_not_start);
    RUN_TEST(test_clock_uses_the_crystal_when_it_starts_and_switches_it_off_when_not);
    RUN_TEST(test_systick_uart_and_timers_are_set_for_the_clock_in_use);
    RUN_TEST(test_uart_brr_is_the_nearest_setting_and_within_1_percent);
    RUN_TEST(test_quadrature_encoders_use_the_timers_encoder_mode);
    RUN_TEST(test_hall_encoders_use_exti_on_their_a_pins_and_stop_the_timers);
    RUN_TEST(test_hall_edge_calls_hook_with_a_and_b_as_0);
    RUN_TEST(test_encoder_count_folds_into_the_record_as_steps);
    RUN_TEST(test_encoder_poll_folds_the_timer_counters);
    RUN_TEST(test_sonar_attach_gives_each_echo_its_own_line_on_both_edges);
    RUN_TEST(test_echo_edge_on_each_line_calls_hook_with_its_sonar_and_level);
    RUN_TEST(test_echo_edge_of_a_sonar_beyond_count_is_ignored);
    RUN_TEST(test_shared_trigger_pin_pulses_once_per_group_firing);
    RUN_TEST(test_sonars_sharing_a_trigger_are_always_in_the_same_group);
    RUN_TEST(test_pin_map_uses_each_pin_once_and_keeps_the_boards_pins_free);
    RUN_TEST(test_encoders_have_timers_with_encoder_mode_and_actuators_others);
    RUN_TEST(test_servo_pulse_is_clamped_and_its_pins_are_tim9);
    RUN_TEST(test_hbridge_duty_scales_8_bits_to_the_20_khz_period_and_sets_dir);
    RUN_TEST(test_iwdg_setting_picks_the_finest_prescaler_for_the_timeout);
    RUN_TEST(test_watchdog_start_and_kick_return);
    RUN_TEST(test_reset_cause_reads_the_rcc_csr_flags);
    return UNITY_END();
}
