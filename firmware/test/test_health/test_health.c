/* Sensor health monitor: encoder stuck / error storm, sonar timeout / zero, latching. */
#include <string.h>
#include <unity.h>

#include "health.h"

static uint16_t s_count[HEALTH_ENC_MAX];
static uint16_t s_edges[HEALTH_ENC_MAX];
static uint32_t s_now_ms;

static const health_params_t P = {1000u, 2000u, 3u, 10u};

void setUp(void)
{
    memset(s_count, 0, sizeof s_count);
    memset(s_edges, 0, sizeof s_edges);
    s_now_ms = 100u;
    health_init(&P, 2u);
}

void tearDown(void) {}

/* n control ticks of 20 ms; wheel i advances by step[i] counts (and edges) per tick. */
static void ticks(uint16_t n, bool driving, uint16_t step0, uint16_t step1, uint8_t ratio)
{
    for (uint16_t k = 0; k < n; k++) {
        s_count[0] = (uint16_t)(s_count[0] + step0);
        s_edges[0] = (uint16_t)(s_edges[0] + step0);
        s_count[1] = (uint16_t)(s_count[1] + step1);
        s_edges[1] = (uint16_t)(s_edges[1] + step1);
        health_encoders(s_now_ms, driving, s_count, s_edges, ratio);
        s_now_ms += 20u;
    }
}

static void test_health_encoder_stuck_latches_after_stuck_time_while_driving(void)
{
    ticks(1, true, 0, 3, 0);
    ticks(49, true, 0, 3, 0); /* 980 ms without a count on wheel 0 */
    TEST_ASSERT_FALSE_MESSAGE(health_encoder_fault(), "not yet: 980 ms < 1000 ms");
    ticks(2, true, 0, 3, 0);
    TEST_ASSERT_TRUE(health_encoder_fault());
    TEST_ASSERT_EQUAL_HEX32(1UL << HEALTH_ENC_STUCK_SHIFT, health_bits());
}

static void test_health_new_stuck_time_applies_at_once(void)
{
    ticks(30, true, 0, 3, 0); /* 600 ms without a count on wheel 0 */
    health_params_t longer = P;
    longer.enc_stuck_ms = 3000u;
    health_set_params(&longer);
    ticks(40, true, 0, 3, 0); /* 1.4 s: past the old 1 s, short of the new 3 s */
    TEST_ASSERT_FALSE_MESSAGE(health_encoder_fault(), "old HLTH_ENC_MS still in force");
    ticks(85, true, 0, 3, 0); /* 3.1 s: the silence kept counting through the change */
    TEST_ASSERT_TRUE(health_encoder_fault());
}

static void test_health_encoder_silent_while_not_driving_is_fine(void)
{
    ticks(200, false, 0, 0, 0);
    TEST_ASSERT_FALSE(health_encoder_fault());
}

static void test_health_encoder_counting_wheel_is_never_stuck(void)
{
    ticks(200, true, 1, 1, 0);
    TEST_ASSERT_EQUAL_HEX32(0u, health_bits());
}

static void test_health_encoder_silence_restarts_when_driving_stops(void)
{
    ticks(40, true, 0, 2, 0); /* 800 ms */
    ticks(1, false, 0, 0, 0);
    ticks(40, true, 0, 2, 0);
    TEST_ASSERT_FALSE(health_encoder_fault());
}

static void test_health_encoder_edge_storm_is_an_error(void)
{
    ticks(2, true, 5, 5, 0);
    ticks(1, true, 2001, 5, 0);
    TEST_ASSERT_EQUAL_HEX32(1UL << HEALTH_ENC_ERROR_SHIFT, health_bits());
}

static void test_health_encoder_error_ratio_of_the_front_end_is_latched(void)
{
    ticks(1, true, 5, 5, 0x02u);
    ticks(1, true, 5, 5, 0x00u);
    TEST_ASSERT_EQUAL_HEX32(1UL << (HEALTH_ENC_ERROR_SHIFT + 1u), health_bits());
}

static void frame(sonar_frame_t *f, uint8_t idx, uint8_t status, uint16_t mm)
{
    memset(f, 0, sizeof *f);
    f->count = 12u;
    f->seq = 1u;
    for (uint8_t i = 0; i < 12u; i++) {
        f->status[i] = SONAR_NO_ECHO;
        f->ranges_mm[i] = 4000u;
    }
    f->status[idx] = status;
    f->ranges_mm[idx] = mm;
}

static void test_health_sonar_timeout_needs_consecutive_fault_frames(void)
{
    sonar_frame_t f, ok;
    frame(&f, 4u, SONAR_FAULT, 0u);
    frame(&ok, 4u, SONAR_VALID, 900u);
    health_sonar(&f);
    health_sonar(&f);
    health_sonar(&ok); /* one good echo restarts the run */
    health_sonar(&f);
    health_sonar(&f);
    TEST_ASSERT_FALSE(health_sonar_fault());
    health_sonar(&f);
    TEST_ASSERT_TRUE(health_sonar_fault());
    TEST_ASSERT_EQUAL_HEX32(1UL << (HEALTH_SONAR_TIMEOUT_SHIFT + 4u), health_bits());
}

static void test_health_sonar_free_space_is_not_a_fault(void)
{
    sonar_frame_t f;
    frame(&f, 0u, SONAR_NO_ECHO, 4000u);
    for (uint8_t k = 0; k < 100u; k++) {
        health_sonar(&f);
    }
    TEST_ASSERT_EQUAL_HEX32(0u, health_bits());
}

static void test_health_sonar_always_zero_latches_after_zero_frames(void)
{
    sonar_frame_t f;
    frame(&f, 11u, SONAR_VALID, 10u);
    for (uint8_t k = 0; k < 9u; k++) {
        health_sonar(&f);
    }
    TEST_ASSERT_FALSE(health_sonar_fault());
    health_sonar(&f);
    TEST_ASSERT_EQUAL_HEX32(1UL << (HEALTH_SONAR_ZERO_SHIFT + 11u), health_bits());
}

static void test_health_sonar_close_but_real_range_is_not_zero(void)
{
    sonar_frame_t f;
    frame(&f, 2u, SONAR_VALID, HEALTH_SONAR_ZERO_MM);
    for (uint8_t k = 0; k < 50u; k++) {
        health_sonar(&f);
    }
    TEST_ASSERT_FALSE(health_sonar_fault());
}

static void test_health_new_bits_are_reported_once_and_clear_relatches(void)
{
    sonar_frame_t f;
    frame(&f, 1u, SONAR_FAULT, 0u);
    for (uint8_t k = 0; k < 3u; k++) {
        health_sonar(&f);
    }
    uint32_t bit = 1UL << (HEALTH_SONAR_TIMEOUT_SHIFT + 1u);
    TEST_ASSERT_EQUAL_HEX32(bit, health_take_new());
    health_sonar(&f);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, health_take_new(), "reported once");
    health_clear();
    TEST_ASSERT_EQUAL_HEX32(0u, health_bits());
    health_sonar(&f);
    health_sonar(&f);
    TEST_ASSERT_EQUAL_HEX32_MESSAGE(0u, health_bits(), "the run starts again after clear");
    health_sonar(&f);
    TEST_ASSERT_EQUAL_HEX32(bit, health_take_new());
}

static void test_health_new_bits_come_one_per_call_lowest_first(void)
{
    sonar_frame_t f;
    frame(&f, 2u, SONAR_FAULT, 0u);
    f.status[7] = SONAR_FAULT;
    for (uint8_t k = 0; k < 3u; k++) {
        health_sonar(&f);
    }
    TEST_ASSERT_EQUAL_HEX32(1UL << (HEALTH_SONAR_TIMEOUT_SHIFT + 2u), health_take_new());
    TEST_ASSERT_EQUAL_HEX32(1UL << (HEALTH_SONAR_TIMEOUT_SHIFT + 7u), health_take_new());
    TEST_ASSERT_EQUAL_HEX32(0u, health_take_new());
}

static void test_health_zero_parameters_switch_checks_off(void)
{
    health_params_t off = {0u, 0u, 0u, 0u};
    health_init(&off, 2u);
    ticks(200, true, 0, 0, 0);
    ticks(1, true, 5000, 0, 0);
    sonar_frame_t f;
    frame(&f, 0u, SONAR_FAULT, 0u);
    for (uint8_t k = 0; k < 50u; k++) {
        health_sonar(&f);
    }
    TEST_ASSERT_EQUAL_HEX32(0u, health_bits());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_health_encoder_stuck_latches_after_stuck_time_while_driving);
    RUN_TEST(test_health_new_stuck_time_applies_at_once);
    RUN_TEST(test_health_encoder_silent_while_not_driving_is_fine);
    RUN_TEST(test_health_encoder_counting_wheel_is_never_stuck);
    RUN_TEST(test_health_encoder_silence_restarts_when_driving_stops);
    RUN_TEST(test_health_encoder_edge_storm_is_an_error);
    RUN_TEST(test_health_encoder_error_ratio_of_the_front_end_is_latched);
    RUN_TEST(test_health_sonar_timeout_needs_consecutive_fault_frames);
    RUN_TEST(test_health_sonar_free_space_is_not_a_fault);
    RUN_TEST(test_health_sonar_always_zero_latches_after_zero_frames);
    RUN_TEST(test_health_sonar_close_but_real_range_is_not_zero);
    RUN_TEST(test_health_new_bits_are_reported_once_and_clear_relatches);
    RUN_TEST(test_health_new_bits_come_one_per_call_lowest_first);
    RUN_TEST(test_health_zero_parameters_switch_checks_off);
    return UNITY_END();
}
