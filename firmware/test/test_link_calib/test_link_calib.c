/* Calibration tables over MAVLink: message <-> table, and the refusal reasons. */
#include <string.h>
#include <unity.h>

#include "calib.h"
#include "link_calib.h"
#include "sim/hal_sim.h"

void setUp(void)
{
    sim_reset();
    calib_init();
}

void tearDown(void) {}

static void test_link_calib_default_steer_table_round_trips_through_message(void)
{
    calib_table_t t, back;
    TEST_ASSERT_TRUE(calib_get_default(CALIB_STEER, &t));
    mavlink_agnav_calib_table_t m;
    link_calib_to_msg(CALIB_STEER, &t, &m);
    TEST_ASSERT_EQUAL_UINT8(t.pos.n + t.neg.n, m.n_points);
    for (uint8_t i = 1; i < m.n_points; i++) {
        TEST_ASSERT_TRUE_MESSAGE(m.pwm[i] >= m.pwm[i - 1u], "points sorted by pwm on the wire");
    }
    TEST_ASSERT_EQUAL_UINT8(0u, link_calib_from_msg(&m, &back));
    TEST_ASSERT_EQUAL_UINT16(t.neutral_pwm, back.neutral_pwm);
    TEST_ASSERT_EQUAL_UINT8(t.pos.n, back.pos.n);
    TEST_ASSERT_EQUAL_UINT8(t.neg.n, back.neg.n);
    TEST_ASSERT_EQUAL_MEMORY(t.pos.pt, back.pos.pt, sizeof(calib_point_t) * t.pos.n);
    TEST_ASSERT_EQUAL_MEMORY(t.neg.pt, back.neg.pt, sizeof(calib_point_t) * t.neg.n);
    TEST_ASSERT_EQUAL(CALIB_OK, calib_validate(CALIB_STEER, &back));
}

static void test_link_calib_speed_table_with_zero_point_keeps_it_on_its_side(void)
{
    calib_table_t t;
    TEST_ASSERT_TRUE(calib_get_default(CALIB_SPEED, &t));
    mavlink_agnav_calib_table_t m;
    link_calib_to_msg(CALIB_SPEED, &t, &m);
    calib_table_t back;
    TEST_ASSERT_EQUAL_UINT8(0u, link_calib_from_msg(&m, &back));
    TEST_ASSERT_EQUAL(CALIB_OK, calib_validate(CALIB_SPEED, &back));
    TEST_ASSERT_EQUAL_INT32(calib_table_value(&t, 80u), calib_table_value(&back, 80u));
}

static void test_link_calib_non_monotone_table_is_refused_with_reason(void)
{
    mavlink_agnav_calib_table_t m;
    memset(&m, 0, sizeof m);
    m.table_id = CALIB_STEER;
    m.neutral_pwm = 133u;
    const uint16_t pwm[6] = {100, 120, 130, 136, 150, 170};
    const int16_t val[6] = {-2400, -900, -300, 300, 1500, 1200}; /* 1500 then 1200: not monotone */
    for (uint8_t i = 0; i < 6u; i++) {
        m.pwm[i] = pwm[i];
        m.value[i] = val[i];
    }
    m.n_points = 6u;
    calib_table_t t;
    TEST_ASSERT_EQUAL_UINT8(0u, link_calib_from_msg(&m, &t));
    TEST_ASSERT_EQUAL_UINT8(AGNAV_CALIB_NON_MONOTONE, link_calib_result(calib_set_table(CALIB_STEER, &t)));
}

static void test_link_calib_out_of_range_angle_is_refused(void)
{
    mavlink_agnav_calib_table_t m;
    memset(&m, 0, sizeof m);
    m.neutral_pwm = 133u;
    const uint16_t pwm[4] = {100, 130, 136, 170};
    const int16_t val[4] = {-2400, -300, 300, 9000}; /* 90 deg */
    for (uint8_t i = 0; i < 4u; i++) {
        m.pwm[i] = pwm[i];
        m.value[i] = val[i];
    }
    m.n_points = 4u;
    calib_table_t t;
    TEST_ASSERT_EQUAL_UINT8(0u, link_calib_from_msg(&m, &t));
    TEST_ASSERT_EQUAL_UINT8(AGNAV_CALIB_OUT_OF_RANGE, link_calib_result(calib_set_table(CALIB_STEER, &t)));
}

static void test_link_calib_too_many_points_on_one_side_is_bad_table(void)
{
    mavlink_agnav_calib_table_t m;
    memset(&m, 0, sizeof m);
    m.neutral_pwm = 0u;
    for (uint8_t i = 0; i < 12u; i++) {
        m.pwm[i] = (uint16_t)(10u + 10u * i);
        m.value[i] = (int16_t)(100 + 100 * i);
    }
    m.n_points = 12u;
    calib_table_t t;
    TEST_ASSERT_EQUAL_UINT8(AGNAV_CALIB_BAD_TABLE, link_calib_from_msg(&m, &t));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_link_calib_default_steer_table_round_trips_through_message);
    RUN_TEST(test_link_calib_speed_table_with_zero_point_keeps_it_on_its_side);
    RUN_TEST(test_link_calib_non_monotone_table_is_refused_with_reason);
    RUN_TEST(test_link_calib_out_of_range_angle_is_refused);
    RUN_TEST(test_link_calib_too_many_points_on_one_side_is_bad_table);
    return UNITY_END();
}
