/* The two-bank flash EEPROM (flash_eeprom) against a simulated NOR flash: erase sets 0xFF,
 * programming only clears bits, and the power can be cut at any erase or program operation
 * (the operation is left half done, everything after it fails) before a "reboot" (fe_init). */
#include <stdio.h>
#include <string.h>
#include <unity.h>

#include "flash_eeprom.h"

#define BANK_BYTES 192u /* 8 header + 64 snapshot + 30 records */
#define EE_SIZE 64u
#define RECORDS ((BANK_BYTES - FE_HEADER_BYTES - EE_SIZE) / 4u)

static uint8_t s_bank[2][BANK_BYTES];
static int32_t s_ops_left; /* operations before the power cut; < 0: no cut */
static bool s_dead;        /* the power is off: nothing changes any more */
static uint16_t s_ops;     /* operations done (counted whether or not they completed) */
static bool s_fail_verify; /* program reports success but leaves the word unchanged (read-back fails) */

typedef enum { OP_FULL, OP_HALF, OP_NONE } op_t;

/* The next erase or program: done, cut halfway (the power goes now), or nothing (no power). */
static op_t next_op(void)
{
    s_ops++;
    if (s_dead) {
        return OP_NONE;
    }
    if (s_ops_left == 0) {
        s_dead = true;
        return OP_HALF;
    }
    if (s_ops_left > 0) {
        s_ops_left--;
    }
    return OP_FULL;
}

static bool sim_erase(uint8_t b)
{
    op_t op = next_op();
    if (op != OP_NONE) {
        memset(s_bank[b], 0xFF, op == OP_FULL ? BANK_BYTES : BANK_BYTES / 2u);
    }
    return op == OP_FULL;
}

static bool sim_program(uint8_t b, uint32_t off, uint32_t w)
{
    TEST_ASSERT_EQUAL_UINT32(0u, off % 4u);
    TEST_ASSERT_TRUE(off + 4u <= BANK_BYTES);
    op_t op = next_op();
    if (s_fail_verify) {
        return true; /* says done, changed nothing */
    }
    uint8_t n = op == OP_FULL ? 4u : op == OP_HALF ? 2u : 0u;
    for (uint8_t k = 0; k < n; k++) {
        s_bank[b][off + k] &= (uint8_t)(w >> (8u * k)); /* NOR: bits only go 1 -> 0 */
    }
    return op == OP_FULL;
}

static const fe_flash_t FLASH = {BANK_BYTES, {s_bank[0], s_bank[1]}, sim_erase, sim_program};
static fe_t s_fe;
static uint8_t s_mirror[EE_SIZE];

static void power_on(void)
{
    s_dead = false;
    s_ops_left = -1;
    s_fail_verify = false;
    fe_init(&s_fe, &FLASH, s_mirror, EE_SIZE);
}

void setUp(void)
{
    memset(s_bank, 0x5A, sizeof s_bank); /* not even erased: garbage from the factory */
    s_ops = 0u;
    power_on();
}

void tearDown(void) {}

static uint8_t read1(uint16_t a)
{
    uint8_t v;
    fe_read(&s_fe, a, &v, 1u);
    return v;
}

static void test_blank_flash_reads_ff_and_is_formatted(void)
{
    for (uint16_t a = 0; a < EE_SIZE; a++) {
        TEST_ASSERT_EQUAL_HEX8(0xFF, read1(a));
    }
    TEST_ASSERT_TRUE(s_fe.usable);
    TEST_ASSERT_EQUAL_HEX8(0x41, s_bank[0][0]); /* "AGEE" little-endian */
    TEST_ASSERT_EQUAL_HEX8(0x47, s_bank[0][1]);
    TEST_ASSERT_EQUAL_UINT32(1u, s_fe.generation);
}

static void test_values_survive_a_reboot(void)
{
    const uint8_t v[5] = {1, 2, 3, 0xFF, 0};
    TEST_ASSERT_TRUE(fe_write(&s_fe, 10u, v, 5u));
    power_on();
    uint8_t got[5];
    fe_read(&s_fe, 10u, got, 5u);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(v, got, 5u);
    TEST_ASSERT_EQUAL_HEX8(0xFF, read1(9u));
}

static void test_unchanged_bytes_cost_no_record(void)
{
    const uint8_t v[4] = {7, 7, 7, 7};
    TEST_ASSERT_TRUE(fe_write(&s_fe, 0u, v, 4u));
    uint32_t next = s_fe.next;
    TEST_ASSERT_TRUE(fe_write(&s_fe, 0u, v, 4u));
    TEST_ASSERT_EQUAL_UINT32(next, s_fe.next);
    const uint8_t w[4] = {7, 8, 7, 7};
    TEST_ASSERT_TRUE(fe_write(&s_fe, 0u, w, 4u));
    TEST_ASSERT_EQUAL_UINT32(next + 4u, s_fe.next);
}

static void test_full_bank_moves_to_the_other_and_survives_reboots(void)
{
    uint8_t ref[EE_SIZE];
    memset(ref, 0xFF, sizeof ref);
    uint32_t seed = 12345u;
    for (uint16_t k = 0; k < 5u * RECORDS; k++) {
        seed = seed * 1103515245u + 12345u;
        uint16_t a = (uint16_t)((seed >> 8) % EE_SIZE);
        uint8_t v = (uint8_t)(seed >> 20);
        TEST_ASSERT_TRUE(fe_write(&s_fe, a, &v, 1u));
        ref[a] = v;
        if (k % 37u == 0u) {
            power_on();
        }
    }
    TEST_ASSERT_TRUE(s_fe.generation >= 4u); /* at least three compactions */
    power_on();
    uint8_t got[EE_SIZE];
    fe_read(&s_fe, 0u, got, EE_SIZE);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(ref, got, EE_SIZE);
}

/* A fixed sequence of writes (with two compactions in it), the power cut before operation k for
 * every k: after the reboot each address holds its value from the last completed write, except
 * the byte being written when the power went, which holds its old or its new value. */
static void test_power_cut_at_any_operation_keeps_every_completed_write(void)
{
    uint16_t total = 0u;
    for (int32_t cut = -1; cut < (int32_t)total || cut == -1; cut++) {
        memset(s_bank, 0xFF, sizeof s_bank);
        s_ops = 0u;
        power_on();
        uint8_t before[EE_SIZE], after[EE_SIZE];
        memset(before, 0xFF, sizeof before);
        memcpy(after, before, sizeof after);
        uint16_t ops0 = s_ops;
        s_ops_left = cut;
        uint32_t seed = 99u;
        for (uint16_t k = 0; k < 2u * RECORDS + 10u && !s_dead; k++) {
            seed = seed * 1103515245u + 12345u;
            uint16_t a = (uint16_t)((seed >> 8) % EE_SIZE);
            uint8_t v = (uint8_t)(seed >> 20);
            memcpy(before, after, sizeof before);
            after[a] = v;
            (void)fe_write(&s_fe, a, &v, 1u);
        }
        if (cut == -1) {
            total = (uint16_t)(s_ops - ops0); /* how many operations the whole sequence takes */
            TEST_ASSERT_TRUE(s_fe.generation >= 3u);
            continue;
        }
        TEST_ASSERT_TRUE(s_dead);
        power_on();
        TEST_ASSERT_TRUE_MESSAGE(s_fe.usable, "usable after the reboot");
        for (uint16_t a = 0; a < EE_SIZE; a++) {
            uint8_t got = read1(a);
            if (got != after[a] && got != before[a]) {
                char msg[64];
                (void)snprintf(msg, sizeof msg, "cut at op %ld: addr %u holds %u", (long)cut, a, got);
                TEST_FAIL_MESSAGE(msg);
            }
        }
        /* and the store goes on working after the cut */
        uint8_t v = 0x42;
        TEST_ASSERT_TRUE(fe_write(&s_fe, 3u, &v, 1u));
        power_on();
        TEST_ASSERT_EQUAL_HEX8(0x42, read1(3u));
    }
    TEST_ASSERT_TRUE(total > 2u * RECORDS);
}

static void test_failed_program_keeps_the_value_in_ram_and_says_so(void)
{
    s_fail_verify = true;
    uint8_t v = 9;
    TEST_ASSERT_FALSE(fe_write(&s_fe, 5u, &v, 1u));
    TEST_ASSERT_FALSE(s_fe.usable);
    TEST_ASSERT_EQUAL_UINT16(1u, s_fe.failures);
    TEST_ASSERT_EQUAL_HEX8(9, read1(5u)); /* until reset */
    power_on();
    TEST_ASSERT_EQUAL_HEX8(0xFF, read1(5u)); /* it never reached the flash */
}

static void test_compaction_at_rest_only_past_the_threshold(void)
{
    uint8_t v = 0;
    for (uint16_t k = 0; k < RECORDS / 2u; k++) { /* exactly half full: not yet */
        v = (uint8_t)(k + 1u);
        TEST_ASSERT_TRUE(fe_write(&s_fe, (uint16_t)(k % EE_SIZE), &v, 1u));
    }
    TEST_ASSERT_FALSE(fe_compact_if_fuller_than(&s_fe, 50u));
    TEST_ASSERT_EQUAL_UINT32(1u, s_fe.generation);
    v = 0xAB;
    TEST_ASSERT_TRUE(fe_write(&s_fe, 40u, &v, 1u)); /* one more record: past half */
    TEST_ASSERT_TRUE(fe_compact_if_fuller_than(&s_fe, 50u));
    TEST_ASSERT_EQUAL_UINT32(2u, s_fe.generation);
    TEST_ASSERT_EQUAL_UINT8(1u, s_fe.active);
    TEST_ASSERT_EQUAL_UINT32(FE_HEADER_BYTES + EE_SIZE, s_fe.next); /* an empty record area */
    TEST_ASSERT_FALSE(fe_compact_if_fuller_than(&s_fe, 50u));
    power_on();
    TEST_ASSERT_EQUAL_HEX8(0xAB, read1(40u));
    TEST_ASSERT_EQUAL_HEX8((uint8_t)(RECORDS / 2u), read1((uint16_t)((RECORDS / 2u - 1u) % EE_SIZE)));
}

static void test_a_full_bank_has_no_room_until_compacted(void)
{
    uint8_t v = 0;
    for (uint16_t k = 0; k < RECORDS; k++) {
        TEST_ASSERT_TRUE_MESSAGE(fe_has_room(&s_fe), "room left before the last record");
        v = (uint8_t)(k + 1u);
        TEST_ASSERT_TRUE(fe_write(&s_fe, (uint16_t)(k % EE_SIZE), &v, 1u));
    }
    TEST_ASSERT_FALSE_MESSAGE(fe_has_room(&s_fe), "the next byte would move banks (an erase)");
    TEST_ASSERT_EQUAL_UINT32(1u, s_fe.generation);
    TEST_ASSERT_TRUE(fe_compact_if_fuller_than(&s_fe, 50u)); /* at rest */
    TEST_ASSERT_TRUE(fe_has_room(&s_fe));
    power_on();
    TEST_ASSERT_EQUAL_HEX8((uint8_t)RECORDS, read1((uint16_t)((RECORDS - 1u) % EE_SIZE)));
}

static void test_write_beyond_the_end_is_clipped_and_refused(void)
{
    const uint8_t v[4] = {1, 2, 3, 4};
    TEST_ASSERT_FALSE(fe_write(&s_fe, EE_SIZE - 2u, v, 4u));
    TEST_ASSERT_EQUAL_HEX8(1, read1(EE_SIZE - 2u));
    TEST_ASSERT_EQUAL_HEX8(2, read1(EE_SIZE - 1u));
    uint8_t out[3];
    fe_read(&s_fe, EE_SIZE - 1u, out, 3u);
    TEST_ASSERT_EQUAL_HEX8(2, out[0]);
    TEST_ASSERT_EQUAL_HEX8(0xFF, out[1]);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_blank_flash_reads_ff_and_is_formatted);
    RUN_TEST(test_values_survive_a_reboot);
    RUN_TEST(test_unchanged_bytes_cost_no_record);
    RUN_TEST(test_full_bank_moves_to_the_other_and_survives_reboots);
    RUN_TEST(test_power_cut_at_any_operation_keeps_every_completed_write);
    RUN_TEST(test_failed_program_keeps_the_value_in_ram_and_says_so);
    RUN_TEST(test_compaction_at_rest_only_past_the_threshold);
    RUN_TEST(test_a_full_bank_has_no_room_until_compacted);
    RUN_TEST(test_write_beyond_the_end_is_clipped_and_refused);
    return UNITY_END();
}
