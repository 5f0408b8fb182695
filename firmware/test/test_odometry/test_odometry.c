/* Unity tests for lib/odometry against closed forms: straight lines,
 * turning in place, constant-curvature arcs for both drive models (including
 * the radius-2 m test circle of ref 002), heading wrap and the trig tables.
 * Expected values use float (single precision is exact enough at the mm
 * level for these ranges); the module itself is integer only. */
#include <math.h>
#include <stdint.h>

#include "odometry.h"
#include "sim/hal_sim.h"
#include "unity.h"

#define TRACK_MM 191
#define PI_F 3.14159265f

static int32_t round_f(float v) { return (int32_t)(v >= 0.0f ? v + 0.5f : v - 0.5f); }

static void init_model(uint8_t model)
{
    odom_cfg_t c = {model, TRACK_MM, 174u};
    TEST_ASSERT_TRUE(odom_init(&c));
}

/* Drive a differential robot along an arc of radius r_mm (centre to the
 * left if r_mm > 0; r_mm == 0 turns in place CCW) for centre travel s_um
 * (for r == 0: each wheel travels s_um) in n equal ticks. Wheel travel is
 * fed as differences of cumulative integer targets so that no rounding
 * accumulates in the test itself. */
static void drive_diff_arc(int32_t r_mm, int32_t s_um, uint16_t n)
{
    int32_t prev_l = 0, prev_r = 0;
    for (uint16_t k = 1; k <= n; k++) {
        int32_t s_k = (int32_t)((int64_t)s_um * k / n);
        int32_t l_k, r_k;
        if (r_mm == 0) {
            l_k = -s_k;
            r_k = s_k;
        } else {
            l_k = (int32_t)((int64_t)s_k * (2 * r_mm - TRACK_MM) / (2 * r_mm));
            r_k = (int32_t)((int64_t)s_k * (2 * r_mm + TRACK_MM) / (2 * r_mm));
        }
        odom_update_diff(l_k - prev_l, r_k - prev_r, 0, 0);
        prev_l = l_k;
        prev_r = r_k;
    }
}

void setUp(void)
{
    sim_reset();
    init_model(ODOM_MODEL_DIFF);
}

void tearDown(void) {}

/* ---- differential drive ------------------------------------------------- */

static void test_odom_diff_straight_line_1m(void)
{
    odom_pose_t p;
    for (uint8_t i = 0; i < 50u; i++) {
        odom_update_diff(20000, 20000, 1000, 1000);
    }
    odom_get(&p);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(1000, p.x_mm, "1 m forward");
    TEST_ASSERT_EQUAL_INT32_MESSAGE(0, p.y_mm, "no drift sideways");
    TEST_ASSERT_EQUAL_INT32(0, p.heading_cdeg);
    TEST_ASSERT_EQUAL_INT32(1000, p.speed_mm_s);
    TEST_ASSERT_EQUAL_INT32(0, p.yaw_rate_cdeg_s);
}

static void test_odom_diff_straight_line_along_set_heading(void)
{
    odom_pose_t p;
    odom_set_pose(100, -200, 3000); /* 30 degrees */
    for (uint8_t i = 0; i < 40u; i++) {
        odom_update_diff(-25000, -25000, -500, -500); /* 1 m backward */
    }
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, 100 - 866, p.x_mm, "x = -cos 30");
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, -200 - 500, p.y_mm, "y = -sin 30");
    TEST_ASSERT_EQUAL_INT32(3000, p.heading_cdeg);
    TEST_ASSERT_EQUAL_INT32(-500, p.speed_mm_s);
}

static void test_odom_diff_turn_in_place_quarter_turn(void)
{
    odom_pose_t p;
    /* Each wheel travels (pi/2) * track/2 = 150.011 mm. */
    drive_diff_arc(0, 150011, 100u);
    odom_update_diff(0, 0, -150, 150);
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, 9000, p.heading_cdeg, "90 deg CCW");
    TEST_ASSERT_EQUAL_INT32_MESSAGE(0, p.x_mm, "centre does not move");
    TEST_ASSERT_EQUAL_INT32(0, p.y_mm);
    /* 300 mm/s over a 191 mm track = 1.5707 rad/s = 9000 cdeg/s */
    TEST_ASSERT_INT32_WITHIN(2, 9000, p.yaw_rate_cdeg_s);
    TEST_ASSERT_EQUAL_INT32(0, p.speed_mm_s);
}

static void test_odom_diff_arc_matches_closed_form(void)
{
    odom_pose_t p;
    const int32_t r_mm = 1500;
    /* Four legs of 1/16 turn each, checked after every leg. */
    const int32_t leg_um = (int32_t)(2.0f * PI_F * 1500000.0f / 16.0f);
    for (uint8_t leg = 1; leg <= 4u; leg++) {
        drive_diff_arc(r_mm, leg_um, 30u);
        odom_get(&p);
        float th = (float)leg * 2.0f * PI_F / 16.0f;
        TEST_ASSERT_INT32_WITHIN_MESSAGE(2, round_f(1500.0f * sinf(th)), p.x_mm, "x = R sin(s/R)");
        TEST_ASSERT_INT32_WITHIN_MESSAGE(2, round_f(1500.0f * (1.0f - cosf(th))), p.y_mm,
                                         "y = R (1 - cos(s/R))");
        TEST_ASSERT_INT32_WITHIN_MESSAGE(2, round_f(th * 18000.0f / PI_F), p.heading_cdeg, "heading");
    }
}

static void test_odom_diff_ref002_circle_radius_2m(void)
{
    odom_pose_t p;
    /* Start on the circle x = 2 cos(phi), y = 2 sin(phi) at phi = 0, heading
     * along the tangent (+90 deg), and drive it once around CCW. */
    odom_set_pose(2000, 0, 9000);
    const int32_t quarter_um = (int32_t)(PI_F * 1000000.0f); /* pi/2 * 2 m */
    for (uint8_t q = 1; q <= 4u; q++) {
        drive_diff_arc(2000, quarter_um, 157u); /* ~20 mm per tick */
        odom_get(&p);
        float phi = (float)q * PI_F / 2.0f;
        TEST_ASSERT_INT32_WITHIN_MESSAGE(3, round_f(2000.0f * cosf(phi)), p.x_mm, "x = 2 cos(phi)");
        TEST_ASSERT_INT32_WITHIN_MESSAGE(3, round_f(2000.0f * sinf(phi)), p.y_mm, "y = 2 sin(phi)");
    }
    TEST_ASSERT_INT32_WITHIN_MESSAGE(3, 9000, p.heading_cdeg, "full turn back to +90 deg");
}

static void test_odom_diff_arc_right_turn_is_mirror_image(void)
{
    odom_pose_t p;
    const int32_t quarter_um = (int32_t)(PI_F * 1000000.0f);
    drive_diff_arc(-2000, quarter_um, 157u); /* centre to the right */
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN(3, 2000, p.x_mm);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(3, -2000, p.y_mm, "turning right goes to -y");
    TEST_ASSERT_INT32_WITHIN(3, -9000, p.heading_cdeg);
}

static void test_odom_diff_keeps_sub_millimetre_steps(void)
{
    odom_pose_t p;
    odom_set_pose(0, 0, 6000); /* 60 degrees */
    for (uint16_t i = 0; i < 10000u; i++) {
        odom_update_diff(100, 101, 0, 0); /* 100.5 um centre: odd sum */
    }
    /* 1005 mm of travel with a 10 mm wheel difference: tiny heading change
     * (10 / 191 rad = 3.0 deg). Closed form for the arc: */
    float r = 1005.0f * 191.0f / 10.0f;
    float th = 10.0f / 191.0f;
    float x = r * (sinf(PI_F / 3.0f + th) - sinf(PI_F / 3.0f));
    float y = r * (cosf(PI_F / 3.0f) - cosf(PI_F / 3.0f + th));
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, round_f(x), p.x_mm, "100 um steps add up (x)");
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, round_f(y), p.y_mm, "100 um steps add up (y)");
    TEST_ASSERT_INT32_WITHIN(1, 6000 + round_f(th * 18000.0f / PI_F), p.heading_cdeg);
}

static void test_odom_diff_splits_one_large_step(void)
{
    odom_pose_t p;
    odom_set_pose(0, 0, 3000);
    odom_update_diff(1000000, 1000000, 0, 0); /* 1 m in one call */
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN(1, 866, p.x_mm);
    TEST_ASSERT_INT32_WITHIN(1, 500, p.y_mm);
    odom_update_diff(-2000000, 2000000, 0, 0); /* large in-place turn */
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN(1, 866, p.x_mm);
    /* 4 m of wheel difference over 191 mm = 20.942 rad = 1199.9 deg */
    int32_t expect = 3000 + round_f(4000.0f / 191.0f * 18000.0f / PI_F);
    while (expect > 18000) {
        expect -= 36000;
    }
    TEST_ASSERT_INT32_WITHIN_MESSAGE(2, expect, p.heading_cdeg, "heading after big turn");
}

static void test_odom_heading_wraps_into_half_open_range(void)
{
    odom_pose_t p;
    drive_diff_arc(0, 300022, 100u); /* 180 degrees */
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, 18000, p.heading_cdeg, "180 is +18000");
    TEST_ASSERT_TRUE(p.heading_cdeg > -18000);
    drive_diff_arc(0, 150011, 50u); /* 270 degrees */
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, -9000, p.heading_cdeg, "270 wraps to -90");
    odom_set_pose(0, 0, -18000);
    odom_get(&p);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(18000, p.heading_cdeg, "-180 reported as +180");
    odom_set_pose(0, 0, 3L * 36000L + 1234L);
    odom_get(&p);
    TEST_ASSERT_EQUAL_INT32(1234, p.heading_cdeg);
}

/* ---- Ackermann ---------------------------------------------------------- */

static void test_odom_ackermann_straight_when_steer_zero(void)
{
    odom_pose_t p;
    init_model(ODOM_MODEL_ACKERMANN);
    for (uint8_t i = 0; i < 50u; i++) {
        odom_update_ackermann(20000, 0, 1000);
    }
    odom_get(&p);
    TEST_ASSERT_EQUAL_INT32(1000, p.x_mm);
    TEST_ASSERT_EQUAL_INT32(0, p.y_mm);
    TEST_ASSERT_EQUAL_INT32(0, p.heading_cdeg);
    TEST_ASSERT_EQUAL_INT32(0, p.yaw_rate_cdeg_s);
}

/* The ref-002 radius-2 m circle driven by the 174 mm wheelbase car:
 * steering atan(0.174 / 2) = 4.97 deg; curvature tan(phi) / L. */
static void test_odom_ackermann_arc_curvature_is_tan_over_wheelbase(void)
{
    odom_pose_t p;
    init_model(ODOM_MODEL_ACKERMANN);
    const int32_t steer_cdeg = 497;
    float tan_phi = tanf((float)steer_cdeg / 100.0f * PI_F / 180.0f);
    float r = 174.0f / tan_phi; /* 2001.1 mm */
    odom_set_pose(2000, 0, 9000);
    for (uint8_t q = 1; q <= 3u; q++) {
        int32_t prev = 0;
        for (uint16_t k = 1; k <= 160u; k++) { /* a quarter circle in ~20 mm ticks */
            int32_t s_k = (int32_t)((float)k * (r * PI_F / 2.0f * 1000.0f) / 160.0f);
            odom_update_ackermann(s_k - prev, steer_cdeg, 1000);
            prev = s_k;
        }
        odom_get(&p);
        /* Centre of the circle at (2000 - r, 0). */
        float phi = (float)q * PI_F / 2.0f;
        TEST_ASSERT_INT32_WITHIN_MESSAGE(3, round_f(2000.0f - r + r * cosf(phi)), p.x_mm, "x on circle");
        TEST_ASSERT_INT32_WITHIN_MESSAGE(3, round_f(r * sinf(phi)), p.y_mm, "y on circle");
    }
    /* yaw rate = v tan(phi) / L = 1000 * 0.08695 / 174 rad/s = 28.63 deg/s */
    TEST_ASSERT_INT32_WITHIN_MESSAGE(3, round_f(1000.0f * tan_phi / 174.0f * 18000.0f / PI_F),
                                     p.yaw_rate_cdeg_s, "yaw rate");
    TEST_ASSERT_INT32_WITHIN_MESSAGE(3, 0, p.heading_cdeg, "90 + 270 deg = 0");
}

static void test_odom_ackermann_right_steer_turns_clockwise(void)
{
    odom_pose_t p;
    init_model(ODOM_MODEL_ACKERMANN);
    const int32_t steer_cdeg = -2000; /* 20 deg right: R = 174 / tan 20 = 478.1 mm */
    float r = 174.0f / tanf(20.0f * PI_F / 180.0f);
    int32_t s_um = round_f(r * PI_F / 4.0f * 1000.0f); /* 45 degrees of arc */
    int32_t prev = 0;
    for (uint8_t k = 1; k <= 40u; k++) {
        int32_t s_k = (int32_t)((int64_t)s_um * k / 40);
        odom_update_ackermann(s_k - prev, steer_cdeg, 500);
        prev = s_k;
    }
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(2, round_f(r * sinf(PI_F / 4.0f)), p.x_mm, "x = R sin");
    TEST_ASSERT_INT32_WITHIN_MESSAGE(2, -round_f(r * (1.0f - cosf(PI_F / 4.0f))), p.y_mm, "y = -R(1-cos)");
    TEST_ASSERT_INT32_WITHIN(3, -4500, p.heading_cdeg);
    TEST_ASSERT_TRUE_MESSAGE(p.yaw_rate_cdeg_s < 0, "clockwise yaw rate");
}

static void test_odom_ackermann_clamps_steering_to_45deg(void)
{
    odom_pose_t a, b;
    init_model(ODOM_MODEL_ACKERMANN);
    odom_update_ackermann(100000, 4500, 0);
    odom_get(&a);
    init_model(ODOM_MODEL_ACKERMANN);
    odom_update_ackermann(100000, 9000, 0); /* beyond the limit */
    odom_get(&b);
    TEST_ASSERT_EQUAL_INT32(a.heading_cdeg, b.heading_cdeg);
    TEST_ASSERT_EQUAL_INT32(a.x_mm, b.x_mm);
    /* 100 mm at tan 45 over 174 mm = 0.5747 rad = 32.93 deg */
    TEST_ASSERT_INT32_WITHIN(2, 3293, a.heading_cdeg);
}

/* ---- tables and conversions --------------------------------------------- */

static void test_odom_sin_cos_table_error_below_1e_4(void)
{
    int32_t worst = 0;
    for (uint16_t i = 0; i < 1000u; i++) {
        uint32_t bam = (uint32_t)i * 4294967u + 12345u; /* 1000 angles around the circle */
        float a = (float)bam * (2.0f * PI_F / 4294967296.0f);
        int32_t es = odom_sin_q15(bam) - round_f(sinf(a) * 32768.0f);
        int32_t ec = odom_cos_q15(bam) - round_f(cosf(a) * 32768.0f);
        es = es < 0 ? -es : es;
        ec = ec < 0 ? -ec : ec;
        worst = es > worst ? es : worst;
        worst = ec > worst ? ec : worst;
    }
    TEST_ASSERT_TRUE_MESSAGE(worst <= 3, "max error 3/32768 < 1e-4");
    TEST_ASSERT_EQUAL_INT32(32768, odom_sin_q15(0x40000000u));
    TEST_ASSERT_EQUAL_INT32(-32768, odom_cos_q15(0x80000000u));
    TEST_ASSERT_EQUAL_INT32(0, odom_sin_q15(0u));
}

static void test_odom_tan_table_relative_error_below_4e_5(void)
{
    for (int32_t c = -4500; c <= 4500; c += 37) {
        float exact = tanf((float)c * PI_F / 18000.0f);
        float got = (float)odom_tan_q24(c) / 16777216.0f;
        float err = got - exact;
        err = err < 0.0f ? -err : err;
        float mag = exact < 0.0f ? -exact : exact;
        /* relative 4e-5 (at 45 deg), plus Q24 rounding near zero */
        TEST_ASSERT_TRUE_MESSAGE(err <= 4e-5f * mag + 2e-7f, "tan table error");
    }
    TEST_ASSERT_EQUAL_INT32(16777216L, odom_tan_q24(4500));
    TEST_ASSERT_EQUAL_INT32(16777216L, odom_tan_q24(6000));
    TEST_ASSERT_EQUAL_INT32(-16777216L, odom_tan_q24(-6000));
    TEST_ASSERT_EQUAL_INT32(0, odom_tan_q24(0));
}

static void test_odom_bam_and_cdeg_round_trip(void)
{
    for (int32_t c = -17999; c <= 18000; c += 499) {
        TEST_ASSERT_EQUAL_INT32(c, odom_cdeg_from_bam(odom_bam_from_cdeg(c)));
    }
    TEST_ASSERT_EQUAL_UINT32(0x40000000u, odom_bam_from_cdeg(9000));
    TEST_ASSERT_EQUAL_UINT32(0xC0000000u, odom_bam_from_cdeg(-9000));
    TEST_ASSERT_EQUAL_UINT32(0x40000000u, odom_bam_from_cdeg(9000 - 36000));
}

static void test_odom_init_uses_defaults_and_rejects_tiny_track(void)
{
    odom_cfg_t bad = {ODOM_MODEL_DIFF, 5u, 0u};
    odom_pose_t p;
    TEST_ASSERT_FALSE(odom_init(&bad));
    TEST_ASSERT_TRUE(odom_init(NULL));
    /* Default wheelbase 174 mm: 174 mm at 45 deg steer -> 1 rad. */
    odom_update_ackermann(174000, 4500, 0);
    odom_get(&p);
    TEST_ASSERT_INT32_WITHIN(2, 5730, p.heading_cdeg);
}

/* odom_cdeg_from_bam's 16-bit split equals the 64-bit formula it replaced, everywhere. */
static void test_odom_cdeg_from_bam_matches_64_bit_reference(void)
{
    static const uint32_t EDGES[8] = {0u, 1u, 0xFFFFFFFFu, 0x80000000u, 0x7FFFFFFFu, 0xFFFFu, 0x10000u, 0xFFFF0000u};
    uint32_t x = 0x9E3779B9u;
    for (uint32_t k = 0; k < 20000u; k++) {
        x = x * 1664525u + 1013904223u; /* LCG: pseudo-random angles */
        uint32_t h = k < 8u ? EDGES[k] : x;
        int64_t v = (int64_t)(int32_t)h * 36000LL + (1LL << 31);
        int32_t c = (int32_t)(v >> 32);
        if (c <= -18000) {
            c = 18000;
        }
        TEST_ASSERT_EQUAL_INT32(c, odom_cdeg_from_bam(h));
    }
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_odom_diff_straight_line_1m);
    RUN_TEST(test_odom_diff_straight_line_along_set_heading);
    RUN_TEST(test_odom_diff_turn_in_place_quarter_turn);
    RUN_TEST(test_odom_diff_arc_matches_closed_form);
    RUN_TEST(test_odom_diff_ref002_circle_radius_2m);
    RUN_TEST(test_odom_diff_arc_right_turn_is_mirror_image);
    RUN_TEST(test_odom_diff_keeps_sub_millimetre_steps);
    RUN_TEST(test_odom_diff_splits_one_large_step);
    RUN_TEST(test_odom_heading_wraps_into_half_open_range);
    RUN_TEST(test_odom_ackermann_straight_when_steer_zero);
    RUN_TEST(test_odom_ackermann_arc_curvature_is_tan_over_wheelbase);
    RUN_TEST(test_odom_ackermann_right_steer_turns_clockwise);
    RUN_TEST(test_odom_ackermann_clamps_steering_to_45deg);
    RUN_TEST(test_odom_sin_cos_table_error_below_1e_4);
    RUN_TEST(test_odom_tan_table_relative_error_below_4e_5);
    RUN_TEST(test_odom_bam_and_cdeg_round_trip);
    RUN_TEST(test_odom_init_uses_defaults_and_rejects_tiny_track);
    RUN_TEST(test_odom_cdeg_from_bam_matches_64_bit_reference);
    return UNITY_END();
}
