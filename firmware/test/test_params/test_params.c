#include <unity.h>

#include "eeprom_record.h"
#include "hal.h"
#include "params.h"
#include "sim/hal_sim.h"

static uint16_t s_timeout_ms;
static int16_t s_trim_cdeg;
static int32_t s_big;

/* Two modules' groups; their rows' indices interleave (0 and 2 in one, 1 in the other), as the
 * firmware's do (ENC_INVERT, appended last, sits in the encoder group with ENC_COUNT). */
static const PARAMS_ROM param_def_t ROWS_A[] = {
    {"LINK_TIMEOUT_MS", 0, PARAM_U16, &s_timeout_ms, 100, 5000, 500},
    {"BIG_VALUE", 2, PARAM_I32, &s_big, -100000, 100000, 42},
};
static const PARAMS_ROM param_def_t ROWS_B[] = {
    {"STEER_TRIM_CDEG", 1, PARAM_I16, &s_trim_cdeg, -500, 500, 0},
};
static const PARAMS_ROM param_group_t GROUP_A = PARAM_GROUP(ROWS_A);
static const PARAMS_ROM param_group_t GROUP_B = PARAM_GROUP(ROWS_B);
static const PARAMS_ROM param_group_ref_t GROUPS[] = {&GROUP_A, &GROUP_B};

/* A boot: the rows' defaults, as main.c's params_init() writes them before params_load(). */
static void reboot(void) { params_init(GROUPS, 2u); }

void setUp(void)
{
    sim_reset();
    reboot();
}

void tearDown(void) {}

/* The parameter record as lib/storage writes it into a slot. */
static void write_record(uint16_t addr) { eeprom_record_write(addr, params_record_bytes(), params_record_byte); }

static void test_params_get_reads_each_type_from_module_variables(void)
{
    s_trim_cdeg = -7;
    TEST_ASSERT_EQUAL_INT32(500, params_get(0u));
    TEST_ASSERT_EQUAL_INT32(-7, params_get(1u));
    TEST_ASSERT_EQUAL_INT32(42, params_get(2u));
    TEST_ASSERT_EQUAL_UINT16(3u, params_count());
}

static void test_params_signed_byte_round_trips_negative_values(void)
{
    static int8_t dir;
    static const PARAMS_ROM param_def_t ONE[] = {{"WALL_TIE_DIR", 0, PARAM_I8, &dir, -1, 1, -1}};
    static const PARAMS_ROM param_group_t G = PARAM_GROUP(ONE);
    static const PARAMS_ROM param_group_ref_t GS[] = {&G};
    dir = 0;
    params_init(GS, 1u);
    TEST_ASSERT_EQUAL_INT8_MESSAGE(-1, dir, "the default of a signed byte");
    TEST_ASSERT_EQUAL(PARAMS_OK, params_set(0u, 1));
    TEST_ASSERT_EQUAL(PARAMS_OK, params_set(0u, -1));
    TEST_ASSERT_EQUAL_INT8(-1, dir);
    TEST_ASSERT_EQUAL_INT32(-1, params_get(0u));
    TEST_ASSERT_EQUAL(PARAMS_OUT_OF_RANGE, params_set(0u, -2));
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

static void test_params_changes_moves_on_every_stored_value_only(void)
{
    uint8_t c0 = params_changes();
    TEST_ASSERT_EQUAL(PARAMS_OUT_OF_RANGE, params_set(1u, 501));
    TEST_ASSERT_EQUAL(PARAMS_UNKNOWN, params_set(3u, 0));
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(c0, params_changes(), "a refused value counted as a change");
    TEST_ASSERT_EQUAL(PARAMS_OK, params_set(1u, 10));
    uint8_t c1 = params_changes();
    TEST_ASSERT_TRUE(c1 != c0);
    write_record(PARAMS_EEPROM_ADDR);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(c1, params_changes(), "saving is not a change");
    TEST_ASSERT_EQUAL(PARAMS_OK, params_load());
    TEST_ASSERT_TRUE_MESSAGE(params_changes() != c1, "a load (PREFLIGHT_STORAGE) must count as a change");
}

static void test_params_record_then_load_round_trips(void)
{
    params_set(0u, 750);
    params_set(2u, -99999);
    write_record(PARAMS_EEPROM_ADDR);
    reboot();
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL(PARAMS_OK, params_load());
    TEST_ASSERT_EQUAL_UINT16(750u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT32(-99999, s_big);
}

static void test_params_load_keeps_defaults_on_corruption(void)
{
    params_set(0u, 750);
    params_set(1u, 120);
    write_record(PARAMS_EEPROM_ADDR);
    sim_eeprom_bytes()[PARAMS_EEPROM_ADDR + 5u] ^= 0x40u; /* inside the first value */
    reboot();
    TEST_ASSERT_EQUAL_MESSAGE(PARAMS_CORRUPT, params_load(), "a bad CRC is corruption, not absence");
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT16_MESSAGE(0, s_trim_cdeg, "no value of a corrupt record is applied");
}

static void test_params_load_keeps_defaults_when_erased(void)
{
    TEST_ASSERT_EQUAL(PARAMS_STORAGE, params_load());
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
}

static void test_params_load_skips_a_stored_value_outside_todays_range(void)
{
    s_timeout_ms = 5000u;
    s_trim_cdeg = 100;
    write_record(PARAMS_EEPROM_ADDR);
    reboot();
    /* Narrower range in a newer firmware: simulate by a row with max 1000. */
    static const PARAMS_ROM param_def_t NARROW[] = {
        {"LINK_TIMEOUT_MS", 0, PARAM_U16, &s_timeout_ms, 100, 1000, 500},
        {"BIG_VALUE", 2, PARAM_I32, &s_big, -100000, 100000, 42},
    };
    static const PARAMS_ROM param_group_t G = PARAM_GROUP(NARROW);
    static const PARAMS_ROM param_group_ref_t GS[] = {&G, &GROUP_B};
    params_init(GS, 2u);
    TEST_ASSERT_EQUAL(PARAMS_STORAGE, params_load());
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT16(100, s_trim_cdeg);
}

static void test_params_load_reports_corrupt_header_and_keeps_defaults(void)
{
    params_set(0u, 750);
    write_record(PARAMS_EEPROM_ADDR);
    sim_eeprom_bytes()[PARAMS_EEPROM_ADDR] ^= 0x01u; /* magic */
    reboot();
    TEST_ASSERT_EQUAL(PARAMS_CORRUPT, params_load());
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
}

/* The firmware that had only rows 0 and 1 (keys are append-only: BIG_VALUE came later). */
static const PARAMS_ROM param_def_t OLDER_A[] = {
    {"LINK_TIMEOUT_MS", 0, PARAM_U16, &s_timeout_ms, 100, 5000, 500},
};
static const PARAMS_ROM param_group_t OLDER_GROUP_A = PARAM_GROUP(OLDER_A);
static const PARAMS_ROM param_group_ref_t OLDER[] = {&OLDER_GROUP_A, &GROUP_B};

static void test_params_load_applies_an_older_shorter_record_and_keeps_new_defaults(void)
{
    params_init(OLDER, 2u);
    params_set(0u, 900);
    params_set(1u, -250);
    write_record(PARAMS_EEPROM_ADDR);
    s_big = 77;
    reboot();
    TEST_ASSERT_EQUAL(PARAMS_OK, params_load());
    TEST_ASSERT_EQUAL_UINT16(900u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT16(-250, s_trim_cdeg);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(42, s_big, "a row the record does not hold keeps its default");
}

static void test_params_load_refuses_a_longer_record_from_a_newer_firmware(void)
{
    write_record(PARAMS_EEPROM_ADDR);
    params_init(OLDER, 2u);
    TEST_ASSERT_EQUAL(PARAMS_STORAGE, params_load());
}

static void test_params_load_takes_the_copy_when_the_main_slot_is_torn(void)
{
    params_set(0u, 750);
    write_record(PARAMS_COPY_ADDR); /* a save cut short: copy written, main slot half rewritten */
    params_set(0u, 600);
    write_record(PARAMS_EEPROM_ADDR);
    sim_eeprom_bytes()[PARAMS_EEPROM_ADDR + 5u] ^= 0x40u;
    reboot();
    TEST_ASSERT_EQUAL(PARAMS_OK, params_load());
    TEST_ASSERT_EQUAL_UINT16(750u, s_timeout_ms);
}

static void test_params_load_prefers_a_whole_main_slot_over_the_copy(void)
{
    params_set(0u, 750);
    write_record(PARAMS_COPY_ADDR);
    params_set(0u, 600);
    write_record(PARAMS_EEPROM_ADDR);
    reboot();
    TEST_ASSERT_EQUAL(PARAMS_OK, params_load());
    TEST_ASSERT_EQUAL_UINT16(600u, s_timeout_ms);
}

static void test_params_record_bytes_are_the_little_endian_layout(void)
{
    params_set(2u, -2);
    TEST_ASSERT_EQUAL_UINT16(4u + 3u * 4u + 2u, params_record_bytes());
    TEST_ASSERT_EQUAL_HEX8(0x1D, params_record_byte(0u)); /* magic 0xA61D */
    TEST_ASSERT_EQUAL_HEX8(0xA6, params_record_byte(1u));
    TEST_ASSERT_EQUAL_HEX8(3u, params_record_byte(2u)); /* count */
    TEST_ASSERT_EQUAL_HEX8(0u, params_record_byte(3u));
    TEST_ASSERT_EQUAL_HEX8(0xF4, params_record_byte(4u)); /* 500 = 0x01F4 */
    TEST_ASSERT_EQUAL_HEX8(0x01, params_record_byte(5u));
    TEST_ASSERT_EQUAL_HEX8(0xFE, params_record_byte(12u)); /* -2 */
    TEST_ASSERT_EQUAL_HEX8(0xFF, params_record_byte(15u));
}

static void test_params_init_writes_every_rows_default_without_counting_a_change(void)
{
    s_timeout_ms = 1u;
    s_trim_cdeg = 77;
    s_big = -5;
    uint8_t c0 = params_changes();
    reboot();
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_INT16(0, s_trim_cdeg);
    TEST_ASSERT_EQUAL_INT32(42, s_big);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(c0, params_changes(), "defaults are not a change");
}

static void test_params_rows_are_found_by_index_across_groups(void)
{
    param_def_t d;
    TEST_ASSERT_EQUAL_UINT16(3u, params_count());
    TEST_ASSERT_TRUE(params_def(1u, &d));
    TEST_ASSERT_EQUAL_STRING("STEER_TRIM_CDEG", d.name);
    TEST_ASSERT_EQUAL_UINT8(1u, d.index);
    TEST_ASSERT_EQUAL_INT32(-500, d.min);
    TEST_ASSERT_TRUE(params_def(2u, &d));
    TEST_ASSERT_EQUAL_STRING("BIG_VALUE", d.name);
    TEST_ASSERT_EQUAL_INT32(42, d.def);
    TEST_ASSERT_FALSE(params_def(3u, &d));
    TEST_ASSERT_EQUAL_INT16(2, params_find("BIG_VALUE"));
    TEST_ASSERT_EQUAL_INT16(1, params_find("STEER_TRIM_CDEG"));
    TEST_ASSERT_EQUAL(PARAMS_OK, params_set(1u, -3));
    TEST_ASSERT_EQUAL_INT16(-3, s_trim_cdeg);
    /* the record holds the values by index, not by group: slot 1 is group B's row */
    TEST_ASSERT_EQUAL_HEX8(0xFD, params_record_byte(4u + 4u * 1u));
    TEST_ASSERT_EQUAL_HEX8(42u, params_record_byte(4u + 4u * 2u));
}

static void test_params_check_finds_a_gap_or_a_duplicate_index(void)
{
    TEST_ASSERT_TRUE(params_check());
    static const PARAMS_ROM param_def_t DUP[] = {{"DUP", 0, PARAM_U16, &s_timeout_ms, 0, 10, 0}};
    static const PARAMS_ROM param_def_t GAP[] = {{"GAP", 4, PARAM_U16, &s_timeout_ms, 0, 10, 0}};
    static const PARAMS_ROM param_group_t G_DUP = PARAM_GROUP(DUP);
    static const PARAMS_ROM param_group_t G_GAP = PARAM_GROUP(GAP);
    static const PARAMS_ROM param_group_ref_t WITH_DUP[] = {&GROUP_A, &GROUP_B, &G_DUP};
    static const PARAMS_ROM param_group_ref_t WITH_GAP[] = {&GROUP_A, &GROUP_B, &G_GAP};
    static const PARAMS_ROM param_group_ref_t MISSING[] = {&GROUP_A};
    params_init(WITH_DUP, 3u);
    TEST_ASSERT_FALSE_MESSAGE(params_check(), "index 0 twice");
    params_init(WITH_GAP, 3u);
    TEST_ASSERT_FALSE_MESSAGE(params_check(), "rows 0, 1, 2, 4: no row 3");
    params_init(MISSING, 1u);
    TEST_ASSERT_FALSE_MESSAGE(params_check(), "no row 1 of 2");
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_params_get_reads_each_type_from_module_variables);
    RUN_TEST(test_params_signed_byte_round_trips_negative_values);
    RUN_TEST(test_params_find_by_name_without_terminator);
    RUN_TEST(test_params_set_refuses_out_of_range_and_keeps_old_value);
    RUN_TEST(test_params_changes_moves_on_every_stored_value_only);
    RUN_TEST(test_params_record_then_load_round_trips);
    RUN_TEST(test_params_load_keeps_defaults_on_corruption);
    RUN_TEST(test_params_load_keeps_defaults_when_erased);
    RUN_TEST(test_params_load_skips_a_stored_value_outside_todays_range);
    RUN_TEST(test_params_load_reports_corrupt_header_and_keeps_defaults);
    RUN_TEST(test_params_load_applies_an_older_shorter_record_and_keeps_new_defaults);
    RUN_TEST(test_params_load_refuses_a_longer_record_from_a_newer_firmware);
    RUN_TEST(test_params_load_takes_the_copy_when_the_main_slot_is_torn);
    RUN_TEST(test_params_load_prefers_a_whole_main_slot_over_the_copy);
    RUN_TEST(test_params_record_bytes_are_the_little_endian_layout);
    RUN_TEST(test_params_init_writes_every_rows_default_without_counting_a_change);
    RUN_TEST(test_params_rows_are_found_by_index_across_groups);
    RUN_TEST(test_params_check_finds_a_gap_or_a_duplicate_index);
    return UNITY_END();
}
