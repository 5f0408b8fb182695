/*
 * The ATmega2560 H-bridge PWM of the AVR HAL backend (Timer4, OC4A = PH3 left, OC4B = PH4 right,
 * 8-bit fast PWM), under simavr (megaatmega2560 env only: the other envs list this suite in
 * test_ignore). Unit-test builds link the sim backend as "the HAL", so the real backend is
 * compiled into this file under other names (avr_hal_*) and the two coexist.
 *
 * ATmega2560 datasheet (2549Q), 17.9.3 Fast PWM Mode: with OCRnx = BOTTOM the output is a narrow
 * spike each period, so a zero duty must not leave the compare output connected. The checks read
 * the registers the backend wrote: TCCR4A (COM4x1:0 connect OC4x to the pin), PORTH (the pin level
 * while OC4x is disconnected), DDRH (the output driver) and OCR4x.
 */
#include "../hal_avr_under_test.h"

#include <unity.h>

#define COM_A_MASK ((uint8_t)((1u << COM4A1) | (1u << COM4A0)))
#define COM_B_MASK ((uint8_t)((1u << COM4B1) | (1u << COM4B0)))
#define PWM_PINS ((uint8_t)((1u << PH3) | (1u << PH4)))
#define DIR_PINS ((uint8_t)((1u << PH5) | (1u << PH6)))

void setUp(void) { hal_init(); }

void tearDown(void) {}

static void test_hal_init_leaves_timer4_in_8bit_fast_pwm_with_outputs_low(void)
{
    /* Mode 5, 8-bit fast PWM (WGM43:0 = 0101), clk/8: 16 MHz / 8 / 256 = 7.8 kHz. */
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << WGM40, TCCR4A & (uint8_t)((1u << WGM41) | (1u << WGM40)), "WGM41:40");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE((1u << WGM42) | (1u << CS41), TCCR4B, "WGM43:42, clk/8");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(PWM_PINS | DIR_PINS, DDRH & (PWM_PINS | DIR_PINS), "PH3..PH6 outputs");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, TCCR4A & COM_A_MASK, "OC4A disconnected at zero duty");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, TCCR4A & COM_B_MASK, "OC4B disconnected at zero duty");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, PORTH & PWM_PINS, "PH3/PH4 driven low");
}

/* Duty 0 after a running duty: the compare output goes off the pin and the pin is driven low,
 * for each channel on its own (the other channel keeps its PWM). */
static void test_hal_pwm_write_duty_zero_disconnects_compare_output_and_drives_pin_low(void)
{
    hal_pwm_write_duty(0u, 200u, false);
    hal_pwm_write_duty(1u, 90u, true);
    hal_pwm_write_duty(0u, 0u, false);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, TCCR4A & COM_A_MASK, "left: OC4A off the pin at duty 0");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, PORTH & (1u << PH3), "left: PH3 low");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << COM4B1, TCCR4A & COM_B_MASK, "right keeps its PWM");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(90u, OCR4B, "right duty");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << PH6, PORTH & (1u << PH6), "right reverse line high");

    hal_pwm_write_duty(1u, 0u, true);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, TCCR4A & COM_B_MASK, "right: OC4B off the pin at duty 0");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, PORTH & (1u << PH4), "right: PH4 low");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << PH6, PORTH & (1u << PH6), "direction line still set at duty 0");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(PWM_PINS, DDRH & PWM_PINS, "PH3/PH4 stay outputs (driven low, not floating)");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE((1u << WGM42) | (1u << CS41), TCCR4B, "timer keeps running");
}

/* A non-zero duty reconnects OC4x, non-inverting (COM4x1:0 = 10), with OCR4x = duty. */
static void test_hal_pwm_write_duty_nonzero_connects_non_inverting_output(void)
{
    static const uint8_t duties[] = {1u, 128u, 255u};
    for (uint8_t k = 0; k < sizeof duties; k++) {
        hal_pwm_write_duty(0u, 0u, false);
        hal_pwm_write_duty(1u, 0u, false);
        hal_pwm_write_duty(0u, duties[k], true);
        hal_pwm_write_duty(1u, duties[k], false);
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << COM4A1, TCCR4A & COM_A_MASK, "OC4A non-inverting");
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << COM4B1, TCCR4A & COM_B_MASK, "OC4B non-inverting");
        TEST_ASSERT_EQUAL_UINT16_MESSAGE(duties[k], OCR4A, "OCR4A = duty");
        TEST_ASSERT_EQUAL_UINT16_MESSAGE(duties[k], OCR4B, "OCR4B = duty");
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << PH5, PORTH & DIR_PINS, "left reverse, right forward");
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(1u << WGM40, TCCR4A & (uint8_t)((1u << WGM41) | (1u << WGM40)),
                                       "still 8-bit fast PWM");
    }
}

/* Channels beyond HAL_PWM_MAX change nothing. */
static void test_hal_pwm_write_duty_ignores_unknown_channel(void)
{
    hal_pwm_write_duty(0u, 50u, false);
    uint8_t tccr4a = TCCR4A, porth = PORTH;
    hal_pwm_write_duty(2u, 0u, true);
    hal_pwm_write_duty(7u, 99u, true);
    TEST_ASSERT_EQUAL_HEX8(tccr4a, TCCR4A);
    TEST_ASSERT_EQUAL_HEX8(porth, PORTH);
    TEST_ASSERT_EQUAL_UINT16(50u, OCR4A);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_hal_init_leaves_timer4_in_8bit_fast_pwm_with_outputs_low);
    RUN_TEST(test_hal_pwm_write_duty_zero_disconnects_compare_output_and_drives_pin_low);
    RUN_TEST(test_hal_pwm_write_duty_nonzero_connects_non_inverting_output);
    RUN_TEST(test_hal_pwm_write_duty_ignores_unknown_channel);
    return UNITY_END();
}
