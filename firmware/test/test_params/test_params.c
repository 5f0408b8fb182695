#include <unity.h>

#include "hal.h"
#include "params.h"
#include "sim/hal_sim.h"

static uint16_t s_timeout_ms;
static int16_t s_trim_cdeg;
static int32_t s_big;

static const param_def_t TABLE[] = {
    {"LINK_TIMEOUT_MS", PARAM_U16, &s_timeout_ms, 100, 5000, 500},
    {"STEER_TRIM_CDEG", PARAM_I16, &s_trim_cdeg, -500, 500, 0},
    {"BIG_VALUE", PARAM_I32, &s_big, -100000, 100000, 42},
};

void setUp(void)
{
    sim_reset();
    params_init(TABLE, 3u);
    params_reset_defaults();
}

void tearDown(void) {}

static void test_params_defaults_are_written_to_module_variables(void)
{
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT16(0, s_trim_cdeg);
    TEST_ASSERT_EQUAL_INT32(42, s_big);
}

static void test_params_find_by_name_without_terminator(void)
{
    char id[16] = {'S', 'T', 'E', 'E', 'R', '_', 'T', 'R', 'I', 'M', '_', 'C', 'D', 'E', 'G', 0};
    TEST_ASSERT_EQUAL_INT16(1, params_find(id));
    TEST_ASSERT_EQUAL_INT16(-1, params_find("NO_SUCH"));
}

static void test_params_set_refuses_out_of_range_and_keeps_old_value(void)
{
    TEST_ASSERT_EQUAL(PARAMS_OK, params_set(1u, -250));
    TEST_ASSERT_EQUAL_INT16(-250, s_trim_cdeg);
    TEST_ASSERT_EQUAL(PARAMS_OUT_OF_RANGE, params_set(1u, 501));
    TEST_ASSERT_EQUAL_INT16(-250, s_trim_cdeg);
    TEST_ASSERT_EQUAL(PARAMS_UNKNOWN, params_set(3u, 0));
}

static void test_params_save_then_load_round_trips(void)
{
    params_set(0u, 750);
    params_set(2u, -99999);
    TEST_ASSERT_EQUAL(PARAMS_OK, params_save(512u));
    params_reset_defaults();
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL(PARAMS_OK, params_load(512u));
    TEST_ASSERT_EQUAL_UINT16(750u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT32(-99999, s_big);
}

static void test_params_load_falls_back_to_defaults_on_corruption(void)
{
    params_set(0u, 750);
    params_save(512u);
    sim_eeprom_bytes()[512u + 5u] ^= 0x40u; /* inside the first value */
    params_set(0u, 900);
    TEST_ASSERT_EQUAL(PARAMS_STORAGE, params_load(512u));
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
}

static void test_params_load_falls_back_when_erased(void)
{
    params_set(0u, 900);
    TEST_ASSERT_EQUAL(PARAMS_STORAGE, params_load(512u));
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_params_defaults_are_written_to_module_variables);
    RUN_TEST(test_params_find_by_name_without_terminator);
    RUN_TEST(test_params_set_refuses_out_of_range_and_keeps_old_value);
    RUN_TEST(test_params_save_then_load_round_trips);
    RUN_TEST(test_params_load_falls_back_to_defaults_on_corruption);
    RUN_TEST(test_params_load_falls_back_when_erased);
    return UNITY_END();
}
