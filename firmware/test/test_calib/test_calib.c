/* Unity tests for lib/calib (and the CRC-16 it stores with): lookup and
 * inverse against the ref-003 fits, dead band, saturation, validation
 * reasons, EEPROM fallback and round trip. */
#include <stdint.h>

#include "calib.h"
#include "crc16.h"
#include "eeprom_record.h"
#include "hal.h"
#include "sim/hal_sim.h"
#include "unity.h"

static int32_t round_f(float v) { return (int32_t)(v >= 0.0f ? v + 0.5f : v - 0.5f); }

/* A servo-microsecond steering table with left at lower pulse widths. */
static calib_table_t servo_us_table(void)
{
    calib_table_t t = {0};
    t.neutral_pwm = 1500u;
    t.pos.n = 3u;
    t.pos.pt[0].pwm = 1480u; /* 20 us dead band */
    t.pos.pt[0].value = 100;
    t.pos.pt[1].pwm = 1300u;
    t.pos.pt[1].value = 1500;
    t.pos.pt[2].pwm = 1100u;
    t.pos.pt[2].value = 3000;
    t.neg.n = 2u;
    t.neg.pt[0].pwm = 1500u;
    t.neg.pt[0].value = 0;
    t.neg.pt[1].pwm = 1900u;
    t.neg.pt[1].value = -3000;
    return t;
}

void setUp(void)
{
    sim_reset();
    calib_init();
}

void tearDown(void) {}

/* ---- CRC ------------------------------------------------------------------ */

static void test_crc16_ccitt_false_matches_check_value(void)
{
    static const uint8_t msg[9] = {'1', '2', '3', '4', '5', '6', '7', '8', '9'};
    TEST_ASSERT_EQUAL_HEX16(0x29B1u, crc16_ccitt_false(msg, 9u));
    uint16_t c = crc16_ccitt_false_update(CRC16_CCITT_FALSE_INIT, msg, 4u);
    c = crc16_ccitt_false_update(c, &msg[4], 5u);
    TEST_ASSERT_EQUAL_HEX16_MESSAGE(0x29B1u, c, "same result in pieces");
    TEST_ASSERT_EQUAL_HEX16(0xFFFFu, crc16_ccitt_false(msg, 0u));
}

/* ---- default tables vs the ref-003 fits ------------------------------------ */

static void test_calib_default_steer_follows_ref003_fits(void)
{
    for (uint16_t pwm = 134u; pwm <= 170u; pwm++) {
        int32_t fit = round_f(100.0f * (0.6502f * (float)pwm - 86.477f));
        TEST_ASSERT_INT32_WITHIN_MESSAGE(2, fit, calib_value_from_pwm(CALIB_STEER, pwm), "left fit");
    }
    for (uint16_t pwm = 97u; pwm <= 130u; pwm++) {
        int32_t fit = -round_f(100.0f * (-0.6717f * (float)pwm + 89.698f));
        TEST_ASSERT_INT32_WITHIN_MESSAGE(2, fit, calib_value_from_pwm(CALIB_STEER, pwm), "right fit");
    }
    TEST_ASSERT_EQUAL_INT32_MESSAGE(0, calib_value_from_pwm(CALIB_STEER, 133u), "neutral");
    TEST_ASSERT_TRUE_MESSAGE(calib_value_from_pwm(CALIB_STEER, 160u) > 0, "above centre turns left");
}

static void test_calib_steer_saturates_at_24_6_deg(void)
{
    TEST_ASSERT_EQUAL_INT32(2460, calib_value_from_pwm(CALIB_STEER, 171u));
    TEST_ASSERT_EQUAL_INT32(2460, calib_value_from_pwm(CALIB_STEER, 255u));
    TEST_ASSERT_EQUAL_INT32(-2460, calib_value_from_pwm(CALIB_STEER, 96u));
    TEST_ASSERT_EQUAL_INT32(-2460, calib_value_from_pwm(CALIB_STEER, 0u));
    TEST_ASSERT_EQUAL_UINT16(171u, calib_pwm_from_value(CALIB_STEER, 4000));
    TEST_ASSERT_EQUAL_UINT16(96u, calib_pwm_from_value(CALIB_STEER, -4000));
}

/* The int32 extremes saturate like any value beyond the last point: INT32_MIN has no int32
 * magnitude (-INT32_MIN overflows; the native build traps that with -fsanitize=undefined). */
static void test_calib_pwm_from_value_saturates_at_int32_extremes(void)
{
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(96u, calib_pwm_from_value(CALIB_STEER, INT32_MIN), "full right");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(96u, calib_pwm_from_value(CALIB_STEER, INT32_MIN + 1), "full right");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(171u, calib_pwm_from_value(CALIB_STEER, INT32_MAX), "full left");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(109u, calib_pwm_from_value(CALIB_SPEED_LEFT, INT32_MIN),
                                     "no reverse side: the magnitude saturates forward");
    TEST_ASSERT_EQUAL_UINT16(109u, calib_pwm_from_value(CALIB_SPEED_RIGHT, INT32_MAX));
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(1900u, calib_table_pwm(&t, INT32_MIN), "last point of the neg side");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(1100u, calib_table_pwm(&t, INT32_MAX), "last point of the pos side");
}

static void test_calib_steer_pwm_round_trip_within_one_step(void)
{
    for (uint16_t pwm = 96u; pwm <= 171u; pwm++) {
        int32_t a = calib_value_from_pwm(CALIB_STEER, pwm);
        uint16_t back = calib_pwm_from_value(CALIB_STEER, a);
        int32_t err = (int32_t)back - (int32_t)pwm;
        TEST_ASSERT_INT32_WITHIN_MESSAGE(1, 0, err, "pwm -> angle -> pwm");
    }
}

static void test_calib_steer_angle_round_trip_within_half_step(void)
{
    /* One pwm step is 65..68 cdeg; the inverse rounds to the nearest step. */
    for (int32_t a = -2460; a <= 2460; a += 13) {
        uint16_t pwm = calib_pwm_from_value(CALIB_STEER, a);
        int32_t back = calib_value_from_pwm(CALIB_STEER, pwm);
        TEST_ASSERT_INT32_WITHIN_MESSAGE(41, a, back, "angle -> pwm -> angle");
    }
}

static void test_calib_speed_dead_band_returns_zero(void)
{
    for (uint16_t pwm = 0u; pwm <= 32u; pwm++) {
        TEST_ASSERT_EQUAL_INT32_MESSAGE(0, calib_value_from_pwm(CALIB_SPEED, pwm), "below 43.5 cm/s");
    }
    TEST_ASSERT_EQUAL_INT32(446, calib_value_from_pwm(CALIB_SPEED, 33u));
    /* 2.038 * 0x40 - 22.636 = 107.8 cm/s (table 6.2 row 0x40 measured 111.1) */
    TEST_ASSERT_INT32_WITHIN(2, 1078, calib_value_from_pwm(CALIB_SPEED, 0x40u));
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, calib_pwm_from_value(CALIB_SPEED, 300), "too slow: stop");
    TEST_ASSERT_EQUAL_UINT16(0u, calib_pwm_from_value(CALIB_SPEED, 0));
    TEST_ASSERT_EQUAL_UINT16(33u, calib_pwm_from_value(CALIB_SPEED, 446));
}

static void test_calib_speed_saturates_at_max(void)
{
    TEST_ASSERT_EQUAL_INT32(1995, calib_value_from_pwm(CALIB_SPEED, 109u));
    TEST_ASSERT_EQUAL_INT32(1995, calib_value_from_pwm(CALIB_SPEED, 255u));
    TEST_ASSERT_EQUAL_UINT16(109u, calib_pwm_from_value(CALIB_SPEED, 5000));
}

static void test_calib_speed_round_trip_and_sign_magnitude_reverse(void)
{
    for (int32_t v = 446; v <= 1995; v += 17) {
        uint16_t pwm = calib_pwm_from_value(CALIB_SPEED_RIGHT, v);
        int32_t back = calib_value_from_pwm(CALIB_SPEED_RIGHT, pwm);
        TEST_ASSERT_INT32_WITHIN_MESSAGE(11, v, back, "within half a 20 mm/s step");
        TEST_ASSERT_EQUAL_UINT16_MESSAGE(pwm, calib_pwm_from_value(CALIB_SPEED_RIGHT, -v),
                                         "no reverse side: magnitude");
    }
}

static void test_calib_lookup_works_with_left_below_neutral(void)
{
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
    TEST_ASSERT_EQUAL_INT32(1500, calib_value_from_pwm(CALIB_STEER, 1300u));
    TEST_ASSERT_EQUAL_INT32_MESSAGE(0, calib_value_from_pwm(CALIB_STEER, 1490u), "dead band");
    TEST_ASSERT_EQUAL_INT32(2250, calib_value_from_pwm(CALIB_STEER, 1200u));
    TEST_ASSERT_EQUAL_INT32(-1500, calib_value_from_pwm(CALIB_STEER, 1700u));
    TEST_ASSERT_EQUAL_UINT16(1200u, calib_pwm_from_value(CALIB_STEER, 2250));
    TEST_ASSERT_EQUAL_UINT16(1700u, calib_pwm_from_value(CALIB_STEER, -1500));
    TEST_ASSERT_EQUAL_UINT16(1500u, calib_pwm_from_value(CALIB_STEER, 50));
}

/* ---- validation ------------------------------------------------------------ */

static void test_calib_set_table_rejects_non_monotone_and_keeps_active(void)
{
    calib_table_t t;
    TEST_ASSERT_TRUE(calib_get_table(CALIB_STEER, &t));
    t.pos.pt[1].value = 2500; /* above the next point (2460): not monotone */
    TEST_ASSERT_EQUAL_INT_MESSAGE(CALIB_E_NON_MONOTONE, calib_set_table(CALIB_STEER, &t), "values");
    TEST_ASSERT_EQUAL_INT32_MESSAGE(2406, calib_value_from_pwm(CALIB_STEER, 170u), "active unchanged");
    TEST_ASSERT_TRUE(calib_get_table(CALIB_STEER, &t));
    t.neg.pt[2].pwm = 131u; /* closer to neutral than the point before */
    TEST_ASSERT_EQUAL_INT_MESSAGE(CALIB_E_NON_MONOTONE, calib_validate(CALIB_STEER, &t), "pwm");
}

static void test_calib_validate_reports_each_reason(void)
{
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_validate(CALIB_STEER, &t));
    TEST_ASSERT_EQUAL_INT(CALIB_E_BAD_ID, calib_validate(CALIB_TABLE_COUNT, &t));

    t = servo_us_table();
    t.neg.n = 1u;
    TEST_ASSERT_EQUAL_INT(CALIB_E_TOO_FEW_POINTS, calib_validate(CALIB_STEER, &t));
    t.neg.n = 0u;
    TEST_ASSERT_EQUAL_INT_MESSAGE(CALIB_E_TOO_FEW_POINTS, calib_validate(CALIB_STEER, &t),
                                  "steering needs both sides");
    t.neg.n = CALIB_MAX_POINTS + 1u;
    TEST_ASSERT_EQUAL_INT(CALIB_E_TOO_MANY_POINTS, calib_validate(CALIB_STEER, &t));

    t = servo_us_table();
    t.pos.pt[2].value = 4600; /* 46 deg */
    TEST_ASSERT_EQUAL_INT(CALIB_E_VALUE_RANGE, calib_validate(CALIB_STEER, &t));
    TEST_ASSERT_EQUAL_INT_MESSAGE(CALIB_OK, calib_validate(CALIB_SPEED, &t), "4.6 m/s is a fine speed");
    t.pos.pt[2].value = 12000;
    TEST_ASSERT_EQUAL_INT(CALIB_E_VALUE_RANGE, calib_validate(CALIB_SPEED, &t));

    t = servo_us_table();
    t.neg.pt[1].pwm = 3100u;
    TEST_ASSERT_EQUAL_INT(CALIB_E_PWM_RANGE, calib_validate(CALIB_STEER, &t));

    t = servo_us_table();
    t.neg.pt[1].pwm = 1000u; /* right side point below neutral, like the left side */
    TEST_ASSERT_EQUAL_INT(CALIB_E_WRONG_SIDE, calib_validate(CALIB_STEER, &t));
    t = servo_us_table();
    t.neg.pt[1].value = 3000; /* positive value on the negative side */
    TEST_ASSERT_EQUAL_INT(CALIB_E_WRONG_SIDE, calib_validate(CALIB_STEER, &t));
}

static void test_calib_default_tables_pass_validation(void)
{
    calib_table_t t;
    for (uint8_t id = 0; id < (uint8_t)CALIB_TABLE_COUNT; id++) {
        TEST_ASSERT_TRUE(calib_get_default(id, &t));
        TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_validate(id, &t));
    }
}

/* ---- EEPROM ---------------------------------------------------------------- */

/* The record of the active tables as lib/storage writes it into a slot. */
static void write_record(uint16_t addr) { eeprom_record_write(addr, CALIB_RECORD_BYTES, calib_record_byte); }

/* A save as lib/storage ends it: both slots written and read back. */
static void save(void)
{
    write_record(CALIB_COPY_ADDR);
    write_record(CALIB_EEPROM_ADDR);
    calib_saved(true);
}

/* Damage both slots the same way (bit rot the copy cannot make up for). */
static void flip_both(uint16_t offset, uint8_t mask)
{
    sim_eeprom_bytes()[CALIB_EEPROM_ADDR + offset] ^= mask;
    sim_eeprom_bytes()[CALIB_COPY_ADDR + offset] ^= mask;
}

static void test_calib_load_erased_eeprom_falls_back_with_flag(void)
{
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
    TEST_ASSERT_EQUAL_INT(CALIB_E_ERASED, calib_load());
    TEST_ASSERT_BITS_HIGH(CALIB_DEFAULTED, calib_health());
    TEST_ASSERT_EQUAL_INT(CALIB_E_ERASED, calib_last_load_status());
    TEST_ASSERT_EQUAL_INT32_MESSAGE(2406, calib_value_from_pwm(CALIB_STEER, 170u), "defaults active");
}

static void test_calib_save_then_load_round_trip_clears_flag(void)
{
    calib_table_t t = servo_us_table();
    calib_table_t got;
    TEST_ASSERT_BITS_HIGH_MESSAGE(CALIB_DEFAULTED, calib_health(), "defaults after init");
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
    save();
    TEST_ASSERT_EQUAL_HEX8(0x00u, calib_health());

    calib_init(); /* as after a reboot */
    TEST_ASSERT_EQUAL_INT32(2406, calib_value_from_pwm(CALIB_STEER, 170u));
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_load());
    TEST_ASSERT_BITS_LOW_MESSAGE(CALIB_DEFAULTED, calib_health(), "loaded from EEPROM");
    TEST_ASSERT_TRUE(calib_get_table(CALIB_STEER, &got));
    TEST_ASSERT_EQUAL_UINT16(1500u, got.neutral_pwm);
    TEST_ASSERT_EQUAL_UINT8(3u, got.pos.n);
    TEST_ASSERT_EQUAL_UINT16(1100u, got.pos.pt[2].pwm);
    TEST_ASSERT_EQUAL_INT16(-3000, got.neg.pt[1].value);
    TEST_ASSERT_EQUAL_INT32(1500, calib_value_from_pwm(CALIB_STEER, 1300u));
    TEST_ASSERT_EQUAL_INT32_MESSAGE(1995, calib_value_from_pwm(CALIB_SPEED, 200u), "speed table kept");
}

static void test_calib_load_bad_crc_falls_back_with_flag(void)
{
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
    save();
    flip_both(6u + 10u, 0x01u); /* one bit in the steering table */
    TEST_ASSERT_EQUAL_INT(CALIB_E_BAD_CRC, calib_load());
    TEST_ASSERT_BITS_HIGH(CALIB_DEFAULTED, calib_health());
    TEST_ASSERT_EQUAL_INT32_MESSAGE(2406, calib_value_from_pwm(CALIB_STEER, 170u), "defaults active");
}

static void test_calib_load_bad_header_fields_fall_back(void)
{
    uint8_t *ee = sim_eeprom_bytes();
    save();
    ee[CALIB_EEPROM_ADDR + 2u] = ee[CALIB_COPY_ADDR + 2u] = CALIB_LAYOUT_VERSION + 1u;
    TEST_ASSERT_EQUAL_INT(CALIB_E_BAD_VERSION, calib_load());
    TEST_ASSERT_BITS_HIGH(CALIB_DEFAULTED, calib_health());

    save();
    ee[CALIB_EEPROM_ADDR + 4u] = ee[CALIB_COPY_ADDR + 4u] = 0x10u;
    TEST_ASSERT_EQUAL_INT(CALIB_E_BAD_LENGTH, calib_load());

    save();
    ee[CALIB_EEPROM_ADDR + 0u] = ee[CALIB_COPY_ADDR + 0u] = 0x00u;
    TEST_ASSERT_EQUAL_INT(CALIB_E_BAD_MAGIC, calib_load());
    TEST_ASSERT_BITS_HIGH(CALIB_DEFAULTED, calib_health());
}

static void test_calib_load_rejects_invalid_table_with_good_crc(void)
{
    uint8_t *ee = sim_eeprom_bytes();
    save();
    /* Steering pos side, point 1 value (offset 2 + 1 + 4 + 2): 2406 -> 0x7FFF, in both slots. */
    for (uint8_t k = 0; k < 2u; k++) {
        uint16_t a = k == 0u ? CALIB_EEPROM_ADDR : CALIB_COPY_ADDR;
        ee[a + 6u + 9u] = 0xFFu;
        ee[a + 6u + 10u] = 0x7Fu;
        uint16_t crc = crc16_ccitt_false(&ee[a], CALIB_RECORD_BYTES - 2u);
        ee[a + CALIB_RECORD_BYTES - 2u] = (uint8_t)(crc & 0xFFu);
        ee[a + CALIB_RECORD_BYTES - 1u] = (uint8_t)(crc >> 8);
    }
    TEST_ASSERT_EQUAL_INT(CALIB_E_BAD_TABLE, calib_load());
    TEST_ASSERT_BITS_HIGH(CALIB_DEFAULTED, calib_health());
    TEST_ASSERT_EQUAL_INT32(2406, calib_value_from_pwm(CALIB_STEER, 170u));
}

static void test_calib_load_takes_the_copy_when_the_main_slot_is_torn(void)
{
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
    write_record(CALIB_COPY_ADDR); /* a save cut short in its main pass */
    sim_eeprom_bytes()[CALIB_EEPROM_ADDR] = 0xCAu; /* one byte of the new record in an erased slot */
    calib_init();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_load());
    TEST_ASSERT_BITS_LOW(CALIB_DEFAULTED, calib_health());
    TEST_ASSERT_EQUAL_INT32(1500, calib_value_from_pwm(CALIB_STEER, 1300u));
}

static void test_calib_load_prefers_a_whole_main_slot(void)
{
    write_record(CALIB_COPY_ADDR); /* the defaults */
    calib_table_t t = servo_us_table();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
    write_record(CALIB_EEPROM_ADDR);
    calib_init();
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_load());
    TEST_ASSERT_EQUAL_INT32(1500, calib_value_from_pwm(CALIB_STEER, 1300u));
}

static void test_calib_failed_save_is_flagged_and_a_good_one_clears_it(void)
{
    calib_saved(false);
    TEST_ASSERT_BITS_HIGH(CALIB_SAVE_FAILED | CALIB_DEFAULTED, calib_health());
    calib_saved(true);
    TEST_ASSERT_EQUAL_HEX8(0x00u, calib_health());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_crc16_ccitt_false_matches_check_value);
    RUN_TEST(test_calib_default_steer_follows_ref003_fits);
    RUN_TEST(test_calib_steer_saturates_at_24_6_deg);
    RUN_TEST(test_calib_pwm_from_value_saturates_at_int32_extremes);
    RUN_TEST(test_calib_steer_pwm_round_trip_within_one_step);
    RUN_TEST(test_calib_steer_angle_round_trip_within_half_step);
    RUN_TEST(test_calib_speed_dead_band_returns_zero);
    RUN_TEST(test_calib_speed_saturates_at_max);
    RUN_TEST(test_calib_speed_round_trip_and_sign_magnitude_reverse);
    RUN_TEST(test_calib_lookup_works_with_left_below_neutral);
    RUN_TEST(test_calib_set_table_rejects_non_monotone_and_keeps_active);
    RUN_TEST(test_calib_validate_reports_each_reason);
    RUN_TEST(test_calib_default_tables_pass_validation);
    RUN_TEST(test_calib_load_erased_eeprom_falls_back_with_flag);
    RUN_TEST(test_calib_save_then_load_round_trip_clears_flag);
    RUN_TEST(test_calib_load_bad_crc_falls_back_with_flag);
    RUN_TEST(test_calib_load_bad_header_fields_fall_back);
    RUN_TEST(test_calib_load_rejects_invalid_table_with_good_crc);
    RUN_TEST(test_calib_load_takes_the_copy_when_the_main_slot_is_torn);
    RUN_TEST(test_calib_load_prefers_a_whole_main_slot);
    RUN_TEST(test_calib_failed_save_is_flagged_and_a_good_one_clears_it);
    return UNITY_END();
}
