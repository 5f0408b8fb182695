/* Output stage: physical command -> calibration tables -> servo / ESC / H-bridge. */
#include <unity.h>

#include "calib.h"
#include "drive.h"
#include "hal.h"
#include "sim/hal_sim.h"

static void ackermann(void)
{
    drive_cfg_t c = {DRIVE_ACKERMANN, 0u, 0u, 0u};
    drive_init(&c);
}

void setUp(void)
{
    sim_reset();
    calib_init();
    ackermann();
}

void tearDown(void) {}

static void test_drive_takes_only_byte_tables_and_sign_magnitude_speed(void)
{
    calib_table_t t;
    TEST_ASSERT_TRUE(calib_get_default(CALIB_STEER, &t));
    TEST_ASSERT_TRUE_MESSAGE(drive_table_fits(CALIB_STEER, &t), "the default steering table");
    TEST_ASSERT_TRUE(calib_get_default(CALIB_SPEED, &t));
    TEST_ASSERT_TRUE_MESSAGE(drive_table_fits(CALIB_SPEED, &t), "the default speed table");
    /* a speed table in servo microseconds: valid for calib, full throttle for this stage */
    calib_table_t us = {1500u, {2u, {{1550u, 400}, {1700u, 2000}}}, {0u, {{0u, 0}}}};
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_validate(CALIB_SPEED, &us));
    TEST_ASSERT_FALSE(drive_table_fits(CALIB_SPEED, &us));
    /* bytes, but a non-zero neutral on a speed table: a creep at "stop" */
    calib_table_t creep = {20u, {2u, {{33u, 446}, {109u, 1995}}}, {0u, {{0u, 0}}}};
    TEST_ASSERT_FALSE(drive_table_fits(CALIB_SPEED_RIGHT, &creep));
    /* steering: neutral anywhere in 0..255, no point above 255 */
    TEST_ASSERT_TRUE(calib_get_default(CALIB_STEER, &t));
    t.pos.pt[t.pos.n - 1u].pwm = 256u;
    TEST_ASSERT_FALSE(drive_table_fits(CALIB_STEER, &t));
}

static void test_drive_byte_to_servo_pulse_spans_1000_to_2000_us(void)
{
    TEST_ASSERT_EQUAL_UINT16(1000u, drive_servo_us_from_byte(0u));
    TEST_ASSERT_EQUAL_UINT16(2000u, drive_servo_us_from_byte(255u));
    TEST_ASSERT_EQUAL_UINT16(1522u, drive_servo_us_from_byte(133u));
    TEST_ASSERT_EQUAL_UINT16(2000u, drive_servo_us_from_byte(400u));
}

static void test_drive_esc_pulse_is_signed_around_1500_us(void)
{
    TEST_ASSERT_EQUAL_UINT16(1500u, drive_esc_us_from_byte(100u, 0));
    TEST_ASSERT_EQUAL_UINT16(1696u, drive_esc_us_from_byte(100u, 1));
    TEST_ASSERT_EQUAL_UINT16(1304u, drive_esc_us_from_byte(100u, -1));
}

static void test_drive_stop_centres_steering_and_neutral_throttle(void)
{
    drive_apply(2000, 800);
    drive_stop();
    uint16_t centre = drive_servo_us_from_byte(calib_pwm_from_value(CALIB_STEER, 0));
    TEST_ASSERT_EQUAL_UINT16(centre, sim_servo_us(HAL_SERVO_STEER));
    TEST_ASSERT_EQUAL_UINT16(1500u, sim_servo_us(HAL_SERVO_THROTTLE));
}

static void test_drive_left_steer_goes_through_the_table_to_the_servo(void)
{
    drive_apply(1250, 800);
    uint16_t want = drive_servo_us_from_byte(calib_pwm_from_value(CALIB_STEER, 1250));
    TEST_ASSERT_EQUAL_UINT16(want, sim_servo_us(HAL_SERVO_STEER));
    /* ref 003 table: left turns are above the 133 centre */
    TEST_ASSERT_TRUE(sim_servo_us(HAL_SERVO_STEER) > drive_servo_us_from_byte(133u));
    uint16_t speed_b = calib_pwm_from_value(CALIB_SPEED, 800);
    TEST_ASSERT_EQUAL_UINT16(drive_esc_us_from_byte(speed_b, 1), sim_servo_us(HAL_SERVO_THROTTLE));
    TEST_ASSERT_EQUAL_INT8(1, drive_output()->direction);
}

static void test_drive_speed_in_dead_band_gives_neutral_throttle(void)
{
    drive_apply(0, 100); /* 0.1 m/s is below the car's 0.435 m/s minimum */
    TEST_ASSERT_EQUAL_UINT16(1500u, sim_servo_us(HAL_SERVO_THROTTLE));
}

static void test_drive_reverse_speed_sets_direction_and_lower_pulse(void)
{
    drive_apply(0, -800);
    TEST_ASSERT_EQUAL_INT8(-1, drive_output()->direction);
    TEST_ASSERT_TRUE(sim_servo_us(HAL_SERVO_THROTTLE) < 1500u);
}

static void test_drive_differential_turn_left_slows_left_side(void)
{
    drive_cfg_t c = {DRIVE_DIFFERENTIAL, 400u, 0u, 0u};
    drive_init(&c);
    drive_apply(1500, 1000); /* 15 deg left */
    const drive_output_t *o = drive_output();
    TEST_ASSERT_TRUE(o->left_mm_s < 1000 && o->right_mm_s > 1000);
    /* v (1 -+ tan(15 deg)/2): tan 15 deg = 0.2679 -> 866 / 1134 mm/s */
    TEST_ASSERT_INT16_WITHIN(10, 866, o->left_mm_s);
    TEST_ASSERT_INT16_WITHIN(10, 1134, o->right_mm_s);
    TEST_ASSERT_EQUAL_UINT8(o->left_duty, sim_pwm_duty(0u));
    TEST_ASSERT_TRUE(sim_pwm_duty(1u) > sim_pwm_duty(0u));
    TEST_ASSERT_FALSE(sim_pwm_reverse(0u));
}

static void test_drive_differential_spins_on_the_spot_when_nearly_stopped(void)
{
    drive_cfg_t c = {DRIVE_DIFFERENTIAL, 400u, 300u, 100u};
    drive_init(&c);
    drive_apply(4500, 0); /* full left at standstill: counter-clockwise spin */
    const drive_output_t *o = drive_output();
    TEST_ASSERT_INT16_WITHIN(2, -300, o->left_mm_s);
    TEST_ASSERT_INT16_WITHIN(2, 300, o->right_mm_s);
    TEST_ASSERT_TRUE(sim_pwm_reverse(0u));
    TEST_ASSERT_FALSE(sim_pwm_reverse(1u));
    TEST_ASSERT_EQUAL_UINT8(calib_pwm_from_value(CALIB_SPEED_RIGHT, 300), sim_pwm_duty(1u));
    drive_apply(-2250, 50); /* half right while crawling: still a spin, clockwise */
    TEST_ASSERT_INT16_WITHIN(2, 50 + 150, o->left_mm_s);
    TEST_ASSERT_INT16_WITHIN(2, 50 - 150, o->right_mm_s);
}

static void test_drive_raw_mode_passes_table_units_through(void)
{
    drive_apply_raw(171u, 60u, 1);
    TEST_ASSERT_EQUAL_UINT16(drive_servo_us_from_byte(171u), sim_servo_us(HAL_SERVO_STEER));
    TEST_ASSERT_EQUAL_UINT16(drive_esc_us_from_byte(60u, 1), sim_servo_us(HAL_SERVO_THROTTLE));
}

/* Raw outputs read back through the tables (the limits apply to them): the steering angle and speed
 * the car drives at those bytes, the dead band as 1 mm/s in its direction. */
static void test_drive_raw_outputs_read_as_the_tables_physical_command(void)
{
    int16_t steer = 0, speed = 0;
    drive_raw_physical(171u, 255u, 1, &steer, &speed); /* full lock left, full throttle */
    TEST_ASSERT_EQUAL_INT16(2460, steer);
    TEST_ASSERT_EQUAL_INT16(1995, speed);
    drive_raw_physical(96u, 60u, -1, &steer, &speed);
    TEST_ASSERT_EQUAL_INT16(-2460, steer);
    TEST_ASSERT_INT16_WITHIN(1, -996, speed); /* 446 + 27 * 1549 / 76 mm/s, reverse */
    drive_raw_physical(133u, 20u, 1, &steer, &speed);
    TEST_ASSERT_EQUAL_INT16(0, steer);
    TEST_ASSERT_EQUAL_INT16_MESSAGE(1, speed, "a dead-band byte is still forward");
    drive_raw_physical(133u, 0u, -1, &steer, &speed);
    TEST_ASSERT_EQUAL_INT16(0, speed);
    /* differential: one duty on both sides, no turn, the faster side's table */
    drive_cfg_t c = {DRIVE_DIFFERENTIAL, 0u, 0u, 0u};
    drive_init(&c);
    calib_table_t fast = {0u, {2u, {{10u, 100}, {50u, 3000}}}, {0u, {{0u, 0}}}};
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_SPEED_RIGHT, &fast));
    drive_raw_physical(200u, 255u, 1, &steer, &speed);
    TEST_ASSERT_EQUAL_INT16(0, steer);
    TEST_ASSERT_EQUAL_INT16_MESSAGE(3000, speed, "the right side is the faster one");
    drive_raw_physical(0u, 40u, -1, &steer, &speed);
    TEST_ASSERT_INT16_WITHIN(1, -2275, speed); /* right 100 + 30 * 2900 / 40 beats left 446 + 7 * 1549 / 76 */
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_drive_takes_only_byte_tables_and_sign_magnitude_speed);
    RUN_TEST(test_drive_byte_to_servo_pulse_spans_1000_to_2000_us);
    RUN_TEST(test_drive_esc_pulse_is_signed_around_1500_us);
    RUN_TEST(test_drive_stop_centres_steering_and_neutral_throttle);
    RUN_TEST(test_drive_left_steer_goes_through_the_table_to_the_servo);
    RUN_TEST(test_drive_speed_in_dead_band_gives_neutral_throttle);
    RUN_TEST(test_drive_reverse_speed_sets_direction_and_lower_pulse);
    RUN_TEST(test_drive_differential_turn_left_slows_left_side);
    RUN_TEST(test_drive_differential_spins_on_the_spot_when_nearly_stopped);
    RUN_TEST(test_drive_raw_mode_passes_table_units_through);
    RUN_TEST(test_drive_raw_outputs_read_as_the_tables_physical_command);
    return UNITY_END();
}
