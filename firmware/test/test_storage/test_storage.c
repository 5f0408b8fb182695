/* lib/storage, the background writer of the EEPROM records, against the sim HAL with the AVR's
 * programming time (3.3 ms a byte) and the link task's 2 ms period: it never writes while the EEPROM
 * is busy, at most one byte per tick, the copy slot before the main slot; a power cut after any byte
 * (the byte in flight whole or torn) leaves the previous record or the new one, never neither. */
#include <stdio.h>
#include <string.h>
#include <unity.h>

#include "calib.h"
#include "hal.h"
#include "params.h"
#include "sim/hal_sim.h"
#include "storage.h"

static uint16_t s_a_ms;
static int16_t s_b_cdeg;
static int32_t s_c;

static const PARAMS_ROM param_def_t TABLE[] = {
    {"A_MS", 0, PARAM_U16, &s_a_ms, 0, 60000, 500},
    {"B_CDEG", 1, PARAM_I16, &s_b_cdeg, -9000, 9000, 0},
    {"C_VALUE", 2, PARAM_I32, &s_c, -1000000, 1000000, 42},
};
static const PARAMS_ROM param_group_t GROUP = PARAM_GROUP(TABLE);
static const PARAMS_ROM param_group_ref_t GROUPS[] = {&GROUP};

static uint32_t s_now_us;

/* Two records wired as main.c wires them. */
void storage_record_slots(uint8_t record, uint16_t *main_addr, uint16_t *copy_addr, uint16_t *len)
{
    if (record == STORAGE_PARAMS) {
        *main_addr = PARAMS_EEPROM_ADDR;
        *copy_addr = PARAMS_COPY_ADDR;
        *len = params_record_bytes();
    } else {
        TEST_ASSERT_EQUAL_UINT8(STORAGE_CALIB, record);
        *main_addr = CALIB_EEPROM_ADDR;
        *copy_addr = CALIB_COPY_ADDR;
        *len = CALIB_RECORD_BYTES;
    }
}

uint8_t storage_record_byte(uint8_t record, uint16_t pos)
{
    return record == STORAGE_PARAMS ? params_record_byte(pos) : calib_record_byte(pos);
}
static uint8_t keep[SIM_EEPROM_SIZE]; /* the EEPROM across a power cut */

static void set_values(uint16_t a, int16_t b, int32_t c)
{
    s_a_ms = a;
    s_b_cdeg = b;
    s_c = c;
}

/* A boot: the rows' defaults (params_init), then the stored record. */
static params_result_t boot(void)
{
    params_init(GROUPS, 1u);
    storage_init();
    calib_init();
    return params_load();
}

void setUp(void)
{
    sim_reset();
    sim_eeprom_set_write_us(3300u);
    s_now_us = 1000u;
    sim_time_set_us(s_now_us);
    (void)boot();
}

void tearDown(void) {}

/* One link task: 2 ms later, one storage_tick(). Returns the bytes it programmed. */
static uint32_t tick(void)
{
    s_now_us += 2000u;
    sim_time_set_us(s_now_us);
    uint32_t before = sim_eeprom_writes();
    storage_tick();
    return sim_eeprom_writes() - before;
}

/* Ticks until record is written; returns the ticks taken (fails past limit). */
static uint32_t run_until_done(uint8_t record, uint32_t limit)
{
    uint32_t n = 0;
    while (storage_pending(record)) {
        TEST_ASSERT_TRUE_MESSAGE(n++ < limit, "the write never ended");
        (void)tick();
    }
    return n;
}

static void save_params(void)
{
    storage_request(STORAGE_PARAMS);
    (void)run_until_done(STORAGE_PARAMS, 10000u);
    uint8_t failed;
    TEST_ASSERT_EQUAL_HEX8(STORAGE_BIT(STORAGE_PARAMS), storage_take_done(&failed));
    TEST_ASSERT_EQUAL_HEX8(0u, failed);
}

static void test_a_save_writes_both_slots_a_byte_per_tick_never_while_busy(void)
{
    set_values(750u, -1234, -99999);
    storage_request(STORAGE_PARAMS);
    uint32_t last_write_us = 0u;
    uint32_t writes = 0u;
    while (storage_pending(STORAGE_PARAMS)) {
        uint32_t n = tick();
        TEST_ASSERT_TRUE_MESSAGE(n <= 1u, "more than one byte in a tick");
        if (n == 1u) {
            TEST_ASSERT_TRUE_MESSAGE(writes == 0u || s_now_us - last_write_us >= 3300u, "written while busy");
            last_write_us = s_now_us;
            writes++;
        }
    }
    uint16_t len = params_record_bytes();
    uint32_t changed = 0u; /* bytes of the record that differ from an erased cell (0xFF) */
    for (uint16_t i = 0; i < len; i++) {
        changed += sim_eeprom_bytes()[PARAMS_EEPROM_ADDR + i] != 0xFFu;
    }
    TEST_ASSERT_EQUAL_UINT32(2u * changed, writes);
    TEST_ASSERT_TRUE(changed >= len - 6u);
    TEST_ASSERT_TRUE(storage_slot_ok(PARAMS_COPY_ADDR, len));
    TEST_ASSERT_TRUE(storage_slot_ok(PARAMS_EEPROM_ADDR, len));
    TEST_ASSERT_EQUAL(PARAMS_OK, boot());
    TEST_ASSERT_EQUAL_UINT16(750u, s_a_ms);
    TEST_ASSERT_EQUAL_INT16(-1234, s_b_cdeg);
    TEST_ASSERT_EQUAL_INT32(-99999, s_c);
}

static void test_an_unchanged_record_is_only_read(void)
{
    set_values(750u, 5, 6);
    save_params();
    uint32_t before = sim_eeprom_writes();
    save_params();
    TEST_ASSERT_EQUAL_UINT32(0u, sim_eeprom_writes() - before);
    s_b_cdeg = 7; /* one byte of the value, and the two of the CRC, in each slot */
    before = sim_eeprom_writes();
    save_params();
    TEST_ASSERT_EQUAL_UINT32(6u, sim_eeprom_writes() - before);
}

static bool values_are(uint16_t a, int16_t b, int32_t c) { return s_a_ms == a && s_b_cdeg == b && s_c == c; }

/* Save A, then start saving B and cut the power after `cut` bytes were programmed (the byte in flight
 * garbled when torn): what the next boot loads. 0 = A, 1 = B, -1 = neither. */
static int params_after_cut(uint32_t cut, bool torn)
{
    sim_reset();
    sim_eeprom_set_write_us(3300u);
    (void)boot();
    set_values(1111u, -2222, 333333);
    save_params();
    set_values(4444u, 5555, -666666);
    storage_request(STORAGE_PARAMS);
    uint32_t start = sim_eeprom_writes();
    while (storage_pending(STORAGE_PARAMS) && sim_eeprom_writes() - start < cut) {
        (void)tick();
    }
    if (torn && cut > 0u && sim_eeprom_writes() - start == cut) {
        sim_eeprom_bytes()[sim_eeprom_last_write_addr()] ^= 0x5Au; /* the cut caught this byte programming */
    }
    memcpy(keep, sim_eeprom_bytes(), sizeof keep);
    sim_reset();
    memcpy(sim_eeprom_bytes(), keep, sizeof keep);
    params_result_t r = boot();
    if (r == PARAMS_OK && values_are(1111u, -2222, 333333)) {
        return 0;
    }
    if (r == PARAMS_OK && values_are(4444u, 5555, -666666)) {
        return 1;
    }
    return -1;
}

static void test_a_power_cut_after_any_byte_of_a_parameter_save_leaves_a_whole_record(void)
{
    uint32_t total = 2u * params_record_bytes();
    for (int torn = 0; torn < 2; torn++) {
        int seen = 0;
        for (uint32_t cut = 0; cut <= total; cut++) {
            int got = params_after_cut(cut, torn != 0);
            char why[64];
            snprintf(why, sizeof why, "cut after %u bytes%s", (unsigned)cut, torn ? " (torn)" : "");
            TEST_ASSERT_TRUE_MESSAGE(got >= 0, why);
            TEST_ASSERT_TRUE_MESSAGE(got >= seen, why); /* once the new record loads, it stays */
            seen = got;
        }
        TEST_ASSERT_EQUAL_INT_MESSAGE(1, seen, "the whole save loads the new record");
    }
}

/* The steering table with its outermost left point moved out by `more` cdeg (still a valid table). */
static void calib_steer_outer(int16_t more)
{
    calib_table_t t;
    TEST_ASSERT_TRUE(calib_get_default(CALIB_STEER, &t));
    t.pos.pt[t.pos.n - 1u].value = (int16_t)(t.pos.pt[t.pos.n - 1u].value + more);
    TEST_ASSERT_EQUAL_INT(CALIB_OK, calib_set_table(CALIB_STEER, &t));
}

static int16_t calib_outer(void)
{
    calib_table_t d, t;
    TEST_ASSERT_TRUE(calib_get_default(CALIB_STEER, &d));
    TEST_ASSERT_TRUE(calib_get_table(CALIB_STEER, &t));
    return (int16_t)(t.pos.pt[t.pos.n - 1u].value - d.pos.pt[d.pos.n - 1u].value);
}

static void test_a_power_cut_after_any_byte_of_a_calibration_save_leaves_a_whole_record(void)
{
    const int16_t a = 1, b = 2;
    int seen = 0;
    for (uint32_t cut = 0; cut <= 2u * CALIB_RECORD_BYTES; cut += 1u) {
        sim_reset();
        sim_eeprom_set_write_us(3300u);
        (void)boot();
        calib_steer_outer(a);
        storage_request(STORAGE_CALIB);
        (void)run_until_done(STORAGE_CALIB, 10000u);
        calib_steer_outer(b);
        storage_request(STORAGE_CALIB);
        uint32_t start = sim_eeprom_writes();
        while (storage_pending(STORAGE_CALIB) && sim_eeprom_writes() - start < cut) {
            (void)tick();
        }
        if (cut > 0u && sim_eeprom_writes() - start == cut) {
            sim_eeprom_bytes()[sim_eeprom_last_write_addr()] ^= 0xA5u; /* torn */
        }
        memcpy(keep, sim_eeprom_bytes(), sizeof keep);
        sim_reset();
        memcpy(sim_eeprom_bytes(), keep, sizeof keep);
        (void)boot();
        calib_status_t st = calib_load();
        char why[48];
        snprintf(why, sizeof why, "cut after %u bytes", (unsigned)cut);
        TEST_ASSERT_EQUAL_INT_MESSAGE(CALIB_OK, st, why); /* from the main slot or the copy */
        int16_t n = calib_outer();
        TEST_ASSERT_TRUE_MESSAGE(n == a || n == b, why);
        int got = n == b ? 1 : 0;
        TEST_ASSERT_TRUE_MESSAGE(got >= seen, why);
        seen = got;
    }
    TEST_ASSERT_EQUAL_INT(1, seen);
}

static void test_a_byte_that_does_not_read_back_fails_the_save_and_spares_the_main_slot(void)
{
    set_values(10u, 20, 30);
    save_params();
    set_values(11u, 21, 31);
    storage_request(STORAGE_PARAMS);
    uint32_t start = sim_eeprom_writes();
    while (sim_eeprom_writes() == start) {
        (void)tick();
    }
    sim_eeprom_bytes()[sim_eeprom_last_write_addr()] ^= 0x01u; /* the cell did not take it */
    (void)run_until_done(STORAGE_PARAMS, 10000u);
    uint8_t failed;
    TEST_ASSERT_EQUAL_HEX8(STORAGE_BIT(STORAGE_PARAMS), storage_take_done(&failed));
    TEST_ASSERT_EQUAL_HEX8(STORAGE_BIT(STORAGE_PARAMS), failed);
    TEST_ASSERT_EQUAL(PARAMS_OK, boot());
    TEST_ASSERT_TRUE_MESSAGE(values_are(10u, 20, 30), "the main slot keeps the previous record");
}

static void test_a_request_during_a_write_writes_the_record_again_with_the_new_values(void)
{
    set_values(1u, 2, 3);
    storage_request(STORAGE_PARAMS);
    for (int i = 0; i < 20; i++) {
        (void)tick();
    }
    s_c = 777777;
    storage_request(STORAGE_PARAMS);
    (void)run_until_done(STORAGE_PARAMS, 20000u);
    TEST_ASSERT_EQUAL(PARAMS_OK, boot());
    TEST_ASSERT_EQUAL_INT32(777777, s_c);
}

static void test_records_queue_and_each_is_reported_once(void)
{
    storage_request(STORAGE_CALIB);
    storage_request(STORAGE_PARAMS);
    TEST_ASSERT_TRUE(storage_pending(STORAGE_CALIB));
    TEST_ASSERT_TRUE(storage_pending(STORAGE_PARAMS));
    uint8_t done = 0u, failed = 0u, f;
    for (int i = 0; i < 5000 && (storage_pending(STORAGE_CALIB) || storage_pending(STORAGE_PARAMS)); i++) {
        (void)tick();
        done |= storage_take_done(&f);
        failed |= f;
    }
    TEST_ASSERT_EQUAL_HEX8(STORAGE_BIT(STORAGE_CALIB) | STORAGE_BIT(STORAGE_PARAMS), done);
    TEST_ASSERT_EQUAL_HEX8(0u, failed);
    TEST_ASSERT_EQUAL_HEX8(0u, storage_take_done(&f));
    TEST_ASSERT_TRUE(storage_slot_ok(CALIB_COPY_ADDR, CALIB_RECORD_BYTES));
    TEST_ASSERT_TRUE(storage_slot_ok(CALIB_EEPROM_ADDR, CALIB_RECORD_BYTES));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_a_save_writes_both_slots_a_byte_per_tick_never_while_busy);
    RUN_TEST(test_an_unchanged_record_is_only_read);
    RUN_TEST(test_a_power_cut_after_any_byte_of_a_parameter_save_leaves_a_whole_record);
    RUN_TEST(test_a_power_cut_after_any_byte_of_a_calibration_save_leaves_a_whole_record);
    RUN_TEST(test_a_byte_that_does_not_read_back_fails_the_save_and_spares_the_main_slot);
    RUN_TEST(test_a_request_during_a_write_writes_the_record_again_with_the_new_values);
    RUN_TEST(test_records_queue_and_each_is_reported_once);
    return UNITY_END();
}
