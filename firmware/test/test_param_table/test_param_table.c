/* The firmware's parameters as main.c lists their groups: the indices run 0..N-1, each once, in the
 * order of the EEPROM record and of PARAM_VALUE (keys are append-only: a stored record of an older
 * firmware must load into the same rows), and params_init() writes each row's default. */
#include <string.h>
#include <unity.h>

#define AGNAV_NO_MAIN
#include "../../src/main.c"

/* The stored order: a row is appended at the end, never moved. */
static const char *const ORDER[] = {
    "SYSID_THISMAV",
    "DRIVE_KIND",
    "ENC_COUNT",
    "ENC_MODE",
    "ENC_NM_PER_CNT",
    "TRACK_MM",
    "WHEELBASE_MM",
    "SONAR_COUNT",
    "BHV_MODES",
    "LINK_TIMEOUT_MS",
    "MAX_SPEED_MM_S",
    "MAX_STEER_CDEG",
    "AVOID_STOP_MM",
    "AVOID_BACKOFF_MM",
    "AVOID_WAIT_MS",
    "WALL_R0_MM",
    "WALL_SPEED_MM_S",
    "WALL_CANYON_MS",
    "GOAL_SPEED_MM_S",
    "GOAL_TOL_MM",
    "HOST_TIMEOUT_MS",
    "MAN_TIMEOUT_MS",
    "AVOID_CONE_CDEG",
    "AVOID_MOVE_MM_S",
    "AVOID_STOP_MS",
    "AVOID_BACK_MM_S",
    "AVOID_REAR_MM",
    "WALL_DT_MS",
    "WALL_IMAX_STEPS",
    "WALL_IMIN_STEPS",
    "WALL_DEADBAND",
    "WALL_GAIN_Q4",
    "WALL_TURN_CDEG",
    "WALL_TIE_DIR",
    "GOAL_MIN_MM_S",
    "GOAL_SLOW_MM",
    "HLTH_ENC_MS",
    "HLTH_EDGE_MAX",
    "HLTH_SONAR_FR",
    "HLTH_ZERO_FR",
    "SIGN_TELEM",
    "ENC_INVERT",
};
#define ORDER_COUNT (sizeof ORDER / sizeof ORDER[0])

void setUp(void) { params_init(PARAM_GROUPS, PARAM_GROUP_COUNT); }

void tearDown(void) {}

static void test_param_indices_run_from_0_without_gap_or_duplicate(void)
{
    TEST_ASSERT_EQUAL_UINT16(ORDER_COUNT, params_count());
    TEST_ASSERT_TRUE(params_check());
}

static void test_param_rows_keep_the_stored_order_and_unique_names(void)
{
    for (uint16_t i = 0; i < ORDER_COUNT; i++) {
        param_def_t d;
        TEST_ASSERT_TRUE(params_def(i, &d));
        TEST_ASSERT_EQUAL_STRING(ORDER[i], d.name);
        TEST_ASSERT_EQUAL_INT16(i, params_find(ORDER[i]));
    }
}

static void test_param_init_writes_each_rows_default_within_its_range(void)
{
    for (uint16_t i = 0; i < ORDER_COUNT; i++) {
        param_def_t d;
        TEST_ASSERT_TRUE(params_def(i, &d));
        TEST_ASSERT_TRUE_MESSAGE(d.min <= d.def && d.def <= d.max, ORDER[i]);
        TEST_ASSERT_EQUAL_INT32_MESSAGE(d.def, params_get(i), ORDER[i]);
    }
    TEST_ASSERT_EQUAL_UINT16(500u, behaviour_params.link_timeout_ms);
    TEST_ASSERT_EQUAL_INT8(-1, behaviour_params.wall_tie_dir);
    TEST_ASSERT_EQUAL_UINT16(2000u, health_params.enc_edges_max);
    TEST_ASSERT_EQUAL_UINT8(1u, link_param_sysid);
    TEST_ASSERT_EQUAL_UINT16(174u, odom_param_wheelbase_mm);
    TEST_ASSERT_EQUAL_UINT8(12u, sonar_ring_param_count);
    TEST_ASSERT_EQUAL_UINT8(1u, signing_param_sign_telem);
    TEST_ASSERT_EQUAL_UINT16(191u, drive_params.track_mm);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_param_indices_run_from_0_without_gap_or_duplicate);
    RUN_TEST(test_param_rows_keep_the_stored_order_and_unique_names);
    RUN_TEST(test_param_init_writes_each_rows_default_within_its_range);
    return UNITY_END();
}
