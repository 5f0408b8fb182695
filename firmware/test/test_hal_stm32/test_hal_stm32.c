/*
 * The STM32F405 HAL backend on QEMU netduinoplus2 (stm32f405 env only: the other envs list
 * this suite in test_ignore). Unit-test builds link the sim backend as "the HAL", so the real
 * backend is compiled into this file under other names (stm32_hal_*) and the two coexist.
 *
 * What QEMU 7.2 models, and so what is checked here: SysTick, NVIC, SYSCFG_EXTICR, the EXTI
 * registers, TIM2..TIM5 registers. Not modelled: GPIO (reads 0, writes ignored), RCC, IWDG,
 * and EXTI_SWIER only stores its value (no pending bit, no interrupt), so a software edge is
 * a SWIER write plus the vector pended through NVIC_STIR. Pin levels, the trigger pulse on the
 * wire, PWM waveforms and the watchdog reset are only checkable on a board (docs/hil.md).
 */
#define AGNAV_HAL_STM32_UNDER_TEST 1
#define hal_init stm32_hal_init
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
#define hal_sonar_attach stm32_hal_sonar_attach
#define hal_sonar_trigger stm32_hal_sonar_trigger
#define hal_sonar_poll stm32_hal_sonar_poll
#define hal_servo_write_us stm32_hal_servo_write_us
#define hal_pwm_write_duty stm32_hal_pwm_write_duty
#define hal_eeprom_size stm32_hal_eeprom_size
#define hal_eeprom_read stm32_hal_eeprom_read
#define hal_eeprom_write stm32_hal_eeprom_write
#define hal_eeprom_idle stm32_hal_eeprom_idle
#define hal_watchdog_start stm32_hal_watchdog_start
#define hal_watchdog_kick stm32_hal_watchdog_kick
#define hal_reset_cause stm32_hal_reset_cause
#include "../../lib/hal/stm32/hal_stm32.c"

#include <unity.h>

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

void setUp(void)
{
    s_calls = 0;
    EXTI_SWIER = 0u; /* QEMU keeps software edges a test left unserviced */
    hal_encoder_attach(0u, 0);
    hal_sonar_attach(0u, 0);
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
    hal_sonar_trigger(3u); /* 10 us trigger pulse (GPIO not modelled: only its length) */
    dt = hal_time_us() - t0;
    TEST_ASSERT_TRUE(dt >= BOARD_SONAR_TRIGGER_US);
}

/* ---- encoders on EXTI lines 0..7 ------------------------------------------ */

static void test_encoder_attach_routes_lines_to_port_c_on_both_edges(void)
{
    hal_encoder_attach(2u, on_encoder);
    TEST_ASSERT_EQUAL_HEX32(0x2222u, SYSCFG_EXTICR(0) & 0xFFFFu); /* lines 0..3 <- GPIOC */
    TEST_ASSERT_EQUAL_HEX32(0x000Fu, EXTI_IMR & 0xFFu);
    TEST_ASSERT_EQUAL_HEX32(0x000Fu, EXTI_RTSR & 0x0Fu);
    TEST_ASSERT_EQUAL_HEX32(0x000Fu, EXTI_FTSR & 0x0Fu);
    hal_encoder_attach(4u, on_encoder);
    TEST_ASSERT_EQUAL_HEX32(0x2222u, SYSCFG_EXTICR(1) & 0xFFFFu); /* lines 4..7 */
    TEST_ASSERT_EQUAL_HEX32(0x00FFu, EXTI_IMR & 0xFFu);
    TEST_ASSERT_EQUAL_HEX32(0x1Fu << IRQ_EXTI0, NVIC_ISER0 & (0x1Fu << IRQ_EXTI0));
    TEST_ASSERT_TRUE(NVIC_ISER0 & (1u << IRQ_EXTI9_5));
    TEST_ASSERT_TRUE(NVIC_ISER1 & (1u << (IRQ_EXTI15_10 - 32u)));
    hal_encoder_attach(0u, 0);
    TEST_ASSERT_EQUAL_HEX32(0u, EXTI_IMR & 0xFFu);
}

static void test_encoder_edge_on_each_line_calls_hook_with_its_index(void)
{
    hal_encoder_attach(4u, on_encoder);
    uint32_t t_before = hal_time_us();
    for (uint8_t line = 0; line < 8u; line++) {
        hal_delay_us(20u);
        soft_edge(line);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(line + 1u, s_calls, "one call per edge");
        TEST_ASSERT_EQUAL_UINT8(line / 2u, s_idx[line]);
        TEST_ASSERT_EQUAL_UINT8(0u, s_level[line]); /* ab: QEMU's GPIO reads 0 */
        TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, EXTI_SWIER & (1u << line), "software edge consumed");
    }
    TEST_ASSERT_TRUE((int32_t)(s_t[0] - t_before) >= 20);
    for (uint8_t i = 1; i < 8u; i++) {
        TEST_ASSERT_TRUE_MESSAGE((int32_t)(s_t[i] - s_t[i - 1u]) >= 20, "timestamps increase");
    }
    TEST_ASSERT_TRUE((int32_t)(hal_time_us() - s_t[7]) >= 0);
}

static void test_encoder_edge_beyond_count_is_ignored(void)
{
    hal_encoder_attach(1u, on_encoder);
    soft_edge(2u); /* encoder 1 A: not attached */
    soft_edge(5u); /* encoder 2 B */
    TEST_ASSERT_EQUAL_UINT8(0u, s_calls);
    soft_edge(1u); /* encoder 0 B */
    TEST_ASSERT_EQUAL_UINT8(1u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(0u, s_idx[0]);
    EXTI_SWIER = 0u; /* QEMU keeps the unserviced bits */
}

/* ---- sonar echoes on EXTI lines 8..15 ----------------------------------- */

static void test_sonar_attach_routes_echo_lines_to_the_lower_sonar_of_each_pair(void)
{
    hal_sonar_attach(12u, on_echo);
    /* lines 8..11: sonars 4 (PA8), 6 (PB9), 8 (PB10), 10 (PB11); 12..15: sonars 0..3 on PB */
    TEST_ASSERT_EQUAL_HEX32(0x1110u, SYSCFG_EXTICR(2) & 0xFFFFu);
    TEST_ASSERT_EQUAL_HEX32(0x1111u, SYSCFG_EXTICR(3) & 0xFFFFu);
    TEST_ASSERT_EQUAL_HEX32(0xFF00u, EXTI_IMR & 0xFF00u);
    TEST_ASSERT_EQUAL_HEX32(0xFF00u, EXTI_RTSR & 0xFF00u);
    TEST_ASSERT_EQUAL_HEX32(0xFF00u, EXTI_FTSR & 0xFF00u);
    hal_sonar_attach(3u, on_echo);
    TEST_ASSERT_EQUAL_HEX32(0x7000u, EXTI_IMR & 0xFF00u); /* PB12..PB14 only */
}

static void test_trigger_moves_a_shared_line_to_the_fired_sonar(void)
{
    hal_sonar_attach(12u, on_echo);
    soft_edge(8u);
    TEST_ASSERT_EQUAL_UINT8(1u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(4u, s_idx[0]);
    hal_sonar_trigger(5u); /* PC8 */
    TEST_ASSERT_EQUAL_HEX32(0x2u, SYSCFG_EXTICR(2) & 0xFu);
    TEST_ASSERT_TRUE_MESSAGE(EXTI_IMR & (1u << 8), "line unmasked again");
    soft_edge(8u);
    TEST_ASSERT_EQUAL_UINT8(2u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(5u, s_idx[1]);
    TEST_ASSERT_EQUAL_UINT8(0u, s_level[1]);
    hal_sonar_trigger(11u); /* PC11 */
    TEST_ASSERT_EQUAL_HEX32(0x2u, (SYSCFG_EXTICR(2) >> 12) & 0xFu);
    soft_edge(11u);
    TEST_ASSERT_EQUAL_UINT8(11u, s_idx[2]);
    hal_sonar_trigger(4u); /* back to PA8 */
    TEST_ASSERT_EQUAL_HEX32(0x0u, SYSCFG_EXTICR(2) & 0xFu);
    soft_edge(8u);
    TEST_ASSERT_EQUAL_UINT8(4u, s_idx[3]);
    soft_edge(12u); /* sonar 0, dedicated line */
    TEST_ASSERT_EQUAL_UINT8(0u, s_idx[4]);
    TEST_ASSERT_EQUAL_UINT8(5u, s_calls);
    TEST_ASSERT_TRUE((int32_t)(s_t[4] - s_t[0]) > 0);
}

static void test_echo_edge_of_a_sonar_beyond_count_is_ignored(void)
{
    hal_sonar_attach(2u, on_echo);
    soft_edge(14u); /* sonar 2 */
    soft_edge(8u);  /* sonar 4 */
    TEST_ASSERT_EQUAL_UINT8(0u, s_calls);
    soft_edge(13u); /* sonar 1 */
    TEST_ASSERT_EQUAL_UINT8(1u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(1u, s_idx[0]);
    EXTI_SWIER = 0u;
}

/* ---- the pin map ---------------------------------------------------------- */

static void test_pin_map_uses_each_pin_once_and_keeps_uart_and_swd_free(void)
{
    uint8_t used[BOARD_PORT_COUNT * 16u] = {0};
    const uint8_t fixed[] = {BOARD_UART_TX_PIN, BOARD_UART_RX_PIN, BOARD_PA(13), BOARD_PA(14)};
    for (uint8_t i = 0; i < sizeof fixed; i++) {
        used[fixed[i]]++;
    }
    for (uint8_t i = 0; i < HAL_SONAR_MAX; i++) {
        used[s_trigger_pin[i]]++;
        used[s_echo_pin[i]]++;
        uint8_t line = BOARD_PIN_NUM(s_echo_pin[i]);
        TEST_ASSERT_TRUE_MESSAGE(line >= ECHO_LINE_FIRST, "echo on an encoder line");
    }
    for (uint8_t line = 0; line < 2u * HAL_ENCODER_MAX; line++) {
        used[BOARD_PIN(BOARD_ENCODER_PORT, line)]++;
    }
    for (uint8_t i = 0; i < HAL_SERVO_MAX; i++) {
        used[s_servo_pin[i]]++;
    }
    for (uint8_t i = 0; i < HAL_PWM_MAX; i++) {
        used[s_hbridge_pwm_pin[i]]++;
        used[s_hbridge_dir_pin[i]]++;
    }
    for (uint8_t p = 0; p < sizeof used; p++) {
        TEST_ASSERT_TRUE_MESSAGE(used[p] <= 1u, "pin used twice");
    }
}

/* Two sonars on one EXTI line must never be fired in the same group: for every ring size
 * the sonar ring supports, against the ring's own schedule. */
static void test_sonars_sharing_a_line_are_never_in_the_same_group(void)
{
    for (uint8_t n = 1; n <= SONAR_RING_MAX; n++) {
        sonar_ring_cfg_t cfg = {SONAR_RING_12_SDLG.sensor, n};
        TEST_ASSERT_TRUE(sonar_ring_init(&cfg)); /* attaches to the sim HAL: harmless */
        for (uint8_t i = 0; i < n; i++) {
            for (uint8_t j = (uint8_t)(i + 1u); j < n; j++) {
                if (BOARD_PIN_NUM(s_echo_pin[i]) == BOARD_PIN_NUM(s_echo_pin[j])) {
                    TEST_ASSERT_NOT_EQUAL(BOARD_PIN_PORT(s_echo_pin[i]), BOARD_PIN_PORT(s_echo_pin[j]));
                    TEST_ASSERT_NOT_EQUAL_MESSAGE(sonar_ring_group_of(i), sonar_ring_group_of(j),
                                                  "line sharers fired together");
                }
            }
        }
    }
}

/* ---- actuators (TIM3, TIM4 registers are modelled) ------------------------ */

static void test_servo_timer_is_1_mhz_50_hz_and_clamps_pulses(void)
{
    TEST_ASSERT_EQUAL_UINT32(APB1_TIMER_HZ / 1000000u - 1u, TIM_REG(TIM3_BASE, TIM_PSC));
    TEST_ASSERT_EQUAL_UINT32(19999u, TIM_REG(TIM3_BASE, TIM_ARR));
    TEST_ASSERT_EQUAL_HEX32(0x6868u, TIM_REG(TIM3_BASE, TIM_CCMR1));
    TEST_ASSERT_EQUAL_HEX32(0x11u, TIM_REG(TIM3_BASE, TIM_CCER) & 0x11u);
    TEST_ASSERT_TRUE(TIM_REG(TIM3_BASE, TIM_CR1) & 1u);
    hal_servo_write_us(HAL_SERVO_STEER, 1000u);
    hal_servo_write_us(HAL_SERVO_THROTTLE, 2000u);
    TEST_ASSERT_EQUAL_UINT32(1000u, TIM_REG(TIM3_BASE, TIM_CCR1));
    TEST_ASSERT_EQUAL_UINT32(2000u, TIM_REG(TIM3_BASE, TIM_CCR2));
    hal_servo_write_us(HAL_SERVO_STEER, 5000u);
    hal_servo_write_us(HAL_SERVO_THROTTLE, 0u);
    TEST_ASSERT_EQUAL_UINT32(2200u, TIM_REG(TIM3_BASE, TIM_CCR1));
    TEST_ASSERT_EQUAL_UINT32(800u, TIM_REG(TIM3_BASE, TIM_CCR2));
}

static void test_hbridge_duty_scales_8_bits_to_the_20_khz_period(void)
{
    TEST_ASSERT_EQUAL_UINT32(0u, TIM_REG(TIM4_BASE, TIM_PSC));
    TEST_ASSERT_EQUAL_UINT32(APB1_TIMER_HZ / 20000u - 1u, TIM_REG(TIM4_BASE, TIM_ARR));
    TEST_ASSERT_EQUAL_HEX32(0x6868u, TIM_REG(TIM4_BASE, TIM_CCMR1));
    TEST_ASSERT_EQUAL_HEX32(0x11u, TIM_REG(TIM4_BASE, TIM_CCER) & 0x11u);
    TEST_ASSERT_TRUE(TIM_REG(TIM4_BASE, TIM_CR1) & 1u);
    hal_pwm_write_duty(0u, 255u, false);
    hal_pwm_write_duty(1u, 128u, true);
    TEST_ASSERT_EQUAL_UINT32(TIM_REG(TIM4_BASE, TIM_ARR) + 1u, TIM_REG(TIM4_BASE, TIM_CCR1)); /* 100 % */
    TEST_ASSERT_EQUAL_UINT32(128u * 4200u / 255u, TIM_REG(TIM4_BASE, TIM_CCR2));
    hal_pwm_write_duty(2u, 7u, false); /* no such channel: nothing changes */
    TEST_ASSERT_EQUAL_UINT32(128u * 4200u / 255u, TIM_REG(TIM4_BASE, TIM_CCR2));
    hal_pwm_write_duty(0u, 0u, false);
    TEST_ASSERT_EQUAL_UINT32(0u, TIM_REG(TIM4_BASE, TIM_CCR1));
}

/* ---- watchdog (IWDG is not modelled: the divider maths, and that start returns) ---- */

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

int main(void)
{
    hal_init();
    UNITY_BEGIN();
    RUN_TEST(test_time_us_counts_a_masked_wrap_once);
    RUN_TEST(test_time_us_is_monotonic_and_matches_ms);
    RUN_TEST(test_delay_us_waits_at_least_the_time);
    RUN_TEST(test_encoder_attach_routes_lines_to_port_c_on_both_edges);
    RUN_TEST(test_encoder_edge_on_each_line_calls_hook_with_its_index);
    RUN_TEST(test_encoder_edge_beyond_count_is_ignored);
    RUN_TEST(test_sonar_attach_routes_echo_lines_to_the_lower_sonar_of_each_pair);
    RUN_TEST(test_trigger_moves_a_shared_line_to_the_fired_sonar);
    RUN_TEST(test_echo_edge_of_a_sonar_beyond_count_is_ignored);
    RUN_TEST(test_pin_map_uses_each_pin_once_and_keeps_uart_and_swd_free);
    RUN_TEST(test_sonars_sharing_a_line_are_never_in_the_same_group);
    RUN_TEST(test_servo_timer_is_1_mhz_50_hz_and_clamps_pulses);
    RUN_TEST(test_hbridge_duty_scales_8_bits_to_the_20_khz_period);
    RUN_TEST(test_iwdg_setting_picks_the_finest_prescaler_for_the_timeout);
    RUN_TEST(test_watchdog_start_and_kick_return);
    return UNITY_END();
}
