/* MAVLink 2 signing: key provisioning, rejection and counting of unsigned / wrongly signed /
 * replayed frames, key and timestamp persistence in EEPROM. */
#include <string.h>
#include <unity.h>

#include "hal.h"
#include "link.h"
#include "link_wire.h"
#include "params.h"
#include "signing.h"
#include "storage.h"
#include "sim/hal_sim.h"

#define HOST_SYS 255u
#define HOST_COMP 190u
#define US 1u
#define WINDOW_MS 10000u

static uint16_t s_timeout_ms;
static const PARAMS_ROM param_def_t TABLE[] = {
    {"LINK_TIMEOUT_MS", 0, PARAM_U16, &s_timeout_ms, 100, 5000, 500},
};
static const PARAMS_ROM param_group_t GROUP = PARAM_GROUP(TABLE);
static const PARAMS_ROM param_group_ref_t GROUPS[] = {&GROUP};

static const uint8_t KEY[32] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16,
                                17, 18, 19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32};
static const uint8_t OTHER_KEY[32] = {0xA5};
static const uint8_t ZERO_KEY[32] = {0};
#define T0 500000000000ULL /* host timestamp, 10 us units (~2016) */

static mavlink_message_t s_msg;
static mavlink_signing_t s_host; /* the host's signing state */
static uint32_t s_now_ms;

/* Pack on the host side: sign with key (NULL = unsigned) at host timestamp ts. The robot's
 * firmware shares channel 0's status in this test program, so swap the signing state in. */
static void host_finalize(mavlink_message_t *msg, const uint8_t *key, uint64_t ts, uint8_t min_len, uint8_t len,
                          uint8_t crc_extra)
{
    mavlink_status_t *st = mavlink_get_channel_status(MAVLINK_COMM_0);
    struct __mavlink_signing *saved = st->signing;
    if (key != NULL) {
        memset(&s_host, 0, sizeof s_host);
        s_host.flags = MAVLINK_SIGNING_FLAG_SIGN_OUTGOING;
        s_host.link_id = 1u;
        s_host.timestamp = ts;
        memcpy(s_host.secret_key, key, 32u);
        st->signing = &s_host;
    } else {
        st->signing = NULL;
    }
    mavlink_finalize_message(msg, HOST_SYS, HOST_COMP, min_len, len, crc_extra);
    st->signing = saved;
}

static uint16_t wire(const mavlink_message_t *msg, uint8_t *buf) { return mavlink_msg_to_send_buffer(buf, msg); }

static void feed(const uint8_t *buf, uint16_t len)
{
    wire_put(buf, len);
    link_poll(s_now_ms);
}

/* Drain the robot's output; true when its last frame was signed (n: how many frames there were). */
static bool last_sent_signed(uint8_t *n)
{
    static mavlink_message_t last;
    memset(&last, 0, sizeof last);
    uint8_t k = wire_take(WIRE_ANY_MSG, &last);
    if (n != NULL) {
        *n = k;
    }
    return k > 0u && (last.incompat_flags & MAVLINK_IFLAG_SIGNED) != 0u;
}

/* An e-stop COMMAND_LONG on the wire in buf; returns its length. */
static uint16_t estop_frame(const uint8_t *key, uint64_t ts, float engage, uint8_t *buf)
{
    mavlink_command_long_t c;
    memset(&c, 0, sizeof c);
    c.target_system = US;
    c.target_component = 1u;
    c.command = MAV_CMD_AGNAV_ESTOP;
    c.param1 = engage;
    memcpy(_MAV_PAYLOAD_NON_CONST(&s_msg), &c, MAVLINK_MSG_ID_COMMAND_LONG_LEN);
    s_msg.msgid = MAVLINK_MSG_ID_COMMAND_LONG;
    host_finalize(&s_msg, key, ts, MAVLINK_MSG_ID_COMMAND_LONG_MIN_LEN, MAVLINK_MSG_ID_COMMAND_LONG_LEN,
                  MAVLINK_MSG_ID_COMMAND_LONG_CRC);
    return wire(&s_msg, buf);
}

static void estop(const uint8_t *key, uint64_t ts, float engage)
{
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    feed(buf, estop_frame(key, ts, engage, buf));
}

static void setup_signing(const uint8_t *sign_with, const uint8_t *new_key, uint64_t ts)
{
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    mavlink_setup_signing_t ss;
    memset(&ss, 0, sizeof ss);
    ss.target_system = US;
    ss.target_component = 1u;
    memcpy(ss.secret_key, new_key, 32u);
    ss.initial_timestamp = ts;
    memcpy(_MAV_PAYLOAD_NON_CONST(&s_msg), &ss, MAVLINK_MSG_ID_SETUP_SIGNING_LEN);
    s_msg.msgid = MAVLINK_MSG_ID_SETUP_SIGNING;
    host_finalize(&s_msg, sign_with, ts, MAVLINK_MSG_ID_SETUP_SIGNING_MIN_LEN, MAVLINK_MSG_ID_SETUP_SIGNING_LEN,
                  MAVLINK_MSG_ID_SETUP_SIGNING_CRC);
    feed(buf, wire(&s_msg, buf));
}

static void boot(uint16_t window_ms)
{
    params_init(GROUPS, 1u); /* LINK_TIMEOUT_MS 500 */
    sim_time_set_us(s_now_ms * 1000u);
    link_cfg_t cfg = {US, 1u, 2460, 2000, 0, window_ms, 0};
    storage_init();
    link_init(&cfg);
}

/* Run the link task every 2 ms for ms milliseconds (EEPROM writes happen in the background). */
static void run_ms(uint32_t ms)
{
    for (uint32_t t = 0; t < ms; t += 2u) {
        s_now_ms += 2u;
        sim_time_set_us(s_now_ms * 1000u);
        link_poll(s_now_ms);
        storage_tick(); /* main.c's link task runs both */
    }
}

/* The key record wired as main.c wires it. */
void storage_record_slots(uint8_t record, uint16_t *main_addr, uint16_t *copy_addr, uint16_t *len)
{
    TEST_ASSERT_EQUAL_UINT8(STORAGE_SIGNING_KEY, record);
    *main_addr = SIGNING_KEY_ADDR;
    *copy_addr = SIGNING_KEY_COPY_ADDR;
    *len = SIGNING_KEY_RECORD_BYTES;
}

uint8_t storage_record_byte(uint8_t record, uint16_t pos)
{
    (void)record;
    return signing_key_record_byte(pos);
}

/* Both key slots, and the timestamp slot a new key's timestamp starts, at an AVR EEPROM's pace: a byte
 * per 3.3 ms, so one per second 2 ms task. */
#define KEY_WRITE_MS ((2u * SIGNING_KEY_RECORD_BYTES + SIGNING_TS_SLOT_BYTES) * 4u + 40u)

void setUp(void)
{
    sim_reset();
    sim_eeprom_set_write_us(3300u);
    s_now_ms = 0u;
    boot(WINDOW_MS);
}

void tearDown(void) {}

/* FIPS 180-4 examples: "abc" (one block) and the 56-byte two-block message (padding spills). */
static void test_sha256_matches_fips_examples(void)
{
    static const uint8_t ABC[6] = {0xba, 0x78, 0x16, 0xbf, 0x8f, 0x01};
    static const uint8_t TWO[6] = {0x24, 0x8d, 0x6a, 0x61, 0xd2, 0x06};
    static const uint8_t LONG[6] = {0x41, 0xed, 0xec, 0xe4, 0x2d, 0x63}; /* 1000 x "a" */
    static const char MSG2[] = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
    mavlink_sha256_ctx ctx;
    uint8_t out[6];
    mavlink_sha256_init(&ctx);
    mavlink_sha256_update(&ctx, "abc", 3u);
    mavlink_sha256_final_48(&ctx, out);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(ABC, out, 6);
    mavlink_sha256_init(&ctx);
    mavlink_sha256_update(&ctx, MSG2, 56u);
    mavlink_sha256_final_48(&ctx, out);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(TWO, out, 6);
    mavlink_sha256_init(&ctx);
    for (uint16_t i = 0; i < 1000u; i++) {
        mavlink_sha256_update(&ctx, "a", 1u);
    }
    mavlink_sha256_final_48(&ctx, out);
    TEST_ASSERT_EQUAL_HEX8_ARRAY(LONG, out, 6);
}

static void test_signing_off_without_key_accepts_unsigned(void)
{
    TEST_ASSERT_EQUAL_UINT8(SIGNING_OFF, signing_state());
    estop(NULL, 0u, 1.0f);
    TEST_ASSERT_TRUE(link_state()->estop);
}

static void test_signing_unsigned_key_in_provisioning_window_is_set(void)
{
    setup_signing(NULL, KEY, T0);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_ON, signing_state());
    TEST_ASSERT_TRUE(signing_timestamp() >= T0);
}

static void test_signing_unsigned_key_after_window_is_refused(void)
{
    run_ms(WINDOW_MS + 10u);
    setup_signing(NULL, KEY, T0);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_OFF, signing_state());
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_signing_no_window_after_watchdog_boot(void)
{
    boot(0u); /* main passes 0 after a watchdog or brown-out reset */
    setup_signing(NULL, KEY, T0);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_OFF, signing_state());
}

static void test_signing_with_key_rejects_and_counts_unsigned(void)
{
    setup_signing(NULL, KEY, T0);
    estop(NULL, 0u, 1.0f);
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_unsigned);
}

static void test_signing_with_key_accepts_correctly_signed(void)
{
    setup_signing(NULL, KEY, T0);
    estop(KEY, T0 + 100u, 1.0f);
    TEST_ASSERT_TRUE(link_state()->estop);
}

static void test_signing_with_key_rejects_and_counts_wrong_key(void)
{
    setup_signing(NULL, KEY, T0);
    estop(OTHER_KEY, T0 + 100u, 1.0f);
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_bad_signature);
}

static void test_signing_replayed_frame_is_rejected_and_counted(void)
{
    setup_signing(NULL, KEY, T0);
    estop(KEY, T0 + 100u, 1.0f);
    uint8_t rec[MAVLINK_MAX_PACKET_LEN];
    uint16_t n = wire(&s_msg, rec); /* an eavesdropper records the engage frame */
    estop(KEY, T0 + 200u, 0.0f);    /* the host releases */
    TEST_ASSERT_FALSE(link_state()->estop);
    feed(rec, n);                   /* and plays the old frame back */
    TEST_ASSERT_FALSE_MESSAGE(link_state()->estop, "replay not acted on");
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_replay);
}

static void test_signing_frame_older_than_a_minute_from_a_new_stream_is_rejected(void)
{
    setup_signing(NULL, KEY, T0 + 10000000ULL); /* robot timestamp T0 + 100 s */
    estop(KEY, T0, 1.0f);                       /* first frame of the host's stream, 100 s old */
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_replay);
}

static void test_signing_key_change_signed_with_current_key_is_accepted_after_window(void)
{
    setup_signing(NULL, KEY, T0);
    run_ms(WINDOW_MS + 10u);
    setup_signing(OTHER_KEY, ZERO_KEY, T0 + 2000000ULL); /* wrong key: dropped by the parser */
    TEST_ASSERT_EQUAL_UINT8(SIGNING_ON, signing_state());
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_bad_signature);
    setup_signing(KEY, OTHER_KEY, T0 + 2000100ULL);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_ON, signing_state());
    estop(OTHER_KEY, T0 + 2000200ULL, 1.0f);
    TEST_ASSERT_TRUE_MESSAGE(link_state()->estop, "the new key is in use");
}

static void test_signing_zero_key_signed_clears_signing(void)
{
    setup_signing(NULL, KEY, T0);
    setup_signing(KEY, ZERO_KEY, T0 + 100u);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_OFF, signing_state());
    estop(NULL, 0u, 1.0f);
    TEST_ASSERT_TRUE(link_state()->estop);
}

static void test_signing_key_survives_reboot_via_eeprom(void)
{
    setup_signing(NULL, KEY, T0);
    TEST_ASSERT_TRUE(signing_write_pending());
    run_ms(KEY_WRITE_MS);
    TEST_ASSERT_FALSE_MESSAGE(signing_write_pending(), "the record is written in the background");
    boot(0u);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_ON, signing_state());
    estop(NULL, 0u, 1.0f);
    TEST_ASSERT_FALSE(link_state()->estop);
    estop(KEY, T0 + 1000u, 1.0f);
    TEST_ASSERT_TRUE(link_state()->estop);
}

static void test_signing_corrupt_key_record_fails_closed(void)
{
    setup_signing(NULL, KEY, T0);
    run_ms(KEY_WRITE_MS);
    boot(0u);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SIGNING_ON, signing_state(), "intact before the bit flip");
    sim_eeprom_bytes()[SIGNING_KEY_ADDR + 10u] ^= 0x04u;
    sim_eeprom_bytes()[SIGNING_KEY_COPY_ADDR + 10u] ^= 0x04u;
    boot(0u);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_KEY_CORRUPT, signing_state());
    estop(NULL, 0u, 1.0f);
    estop(KEY, T0 + 1000u, 1.0f);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->estop, "nothing is accepted with a damaged key");
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_unsigned);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_bad_signature);
}

static void test_signing_key_change_cut_short_leaves_a_whole_key(void)
{
    setup_signing(NULL, KEY, T0);
    run_ms(KEY_WRITE_MS);
    boot(WINDOW_MS);
    setup_signing(KEY, OTHER_KEY, T0 + 1000u); /* the change, then a power cut in its main pass */
    uint32_t writes = sim_eeprom_writes();
    while (sim_eeprom_writes() - writes < SIGNING_KEY_RECORD_BYTES + 4u) {
        run_ms(2u);
    }
    boot(0u);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SIGNING_ON, signing_state(), "the copy holds the new key");
    estop(KEY, T0 + 2000u, 1.0f);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->estop, "the old key is gone");
    estop(OTHER_KEY, T0 + 3000u, 1.0f);
    TEST_ASSERT_TRUE(link_state()->estop);
}

static void test_signing_timestamp_is_stored_and_restored_ahead_after_reboot(void)
{
    setup_signing(NULL, KEY, T0);
    run_ms(31000u); /* past one save interval, and the slot write */
    boot(0u);
    TEST_ASSERT_TRUE_MESSAGE(signing_timestamp() >= T0 + 2 * SIGNING_TS_SAVE_INTERVAL,
                             "restored value = stored (>= T0 + 30 s) + one interval");
    /* A frame recorded at T0 (before the reboot) is refused: more than 60 s behind. */
    estop(KEY, T0, 1.0f);
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_replay);
}

static void test_signing_robot_signs_its_telemetry(void)
{
    setup_signing(NULL, KEY, T0);
    (void)last_sent_signed(NULL); /* drain */
    link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("hello"));
    TEST_ASSERT_TRUE(last_sent_signed(NULL));
}

/* SIGN_TELEM = 0: the robot's own frames go out unsigned, received frames are still checked. */
static void test_signing_telemetry_unsigned_when_off_but_commands_still_verified(void)
{
    setup_signing(NULL, KEY, T0);
    signing_set_sign_telemetry(false);
    (void)last_sent_signed(NULL); /* drain */
    link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("hello"));
    uint8_t frames = 0u;
    TEST_ASSERT_FALSE(last_sent_signed(&frames));
    TEST_ASSERT_EQUAL_UINT8(1u, frames);
    run_ms(WINDOW_MS + 10u); /* window closed */
    estop(NULL, T0 + 100000u, 1.0f);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->estop, "unsigned command refused with SIGN_TELEM off");
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_unsigned);
    estop(KEY, T0 + 200000u, 1.0f);
    TEST_ASSERT_TRUE_MESSAGE(link_state()->estop, "signed command accepted");
    signing_set_sign_telemetry(true);
    link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("hello"));
    TEST_ASSERT_TRUE_MESSAGE(last_sent_signed(NULL), "signed again when switched back on");
}

/* With a key, a signed frame is hashed only when the hash (and the signed answer) ends before
 * the next control tick (link_cfg_t.tick_due_us); until then it waits in the UART queue. Nothing
 * is lost or reordered, and after LINK_SHA_MAX_WAITS calls without room it is taken anyway. */
static void test_signing_frame_waits_for_room_before_control_tick_then_is_handled_in_order(void)
{
    static uint32_t due_us;
    link_cfg_t cfg = {US, 1u, 2460, 2000, 0, WINDOW_MS, &due_us};
    link_init(&cfg);
    due_us = hal_time_us() + 1000000u;
    setup_signing(NULL, KEY, T0);
    TEST_ASSERT_EQUAL_UINT8(SIGNING_ON, signing_state());
    uint16_t frames0 = link_state()->rx_frames;
    static uint8_t buf[2u * MAVLINK_MAX_PACKET_LEN];
    uint16_t n = estop_frame(KEY, T0 + 100u, 1.0f, buf);
    n = (uint16_t)(n + estop_frame(KEY, T0 + 200u, 0.0f, buf + n)); /* engage, then release */
    wire_put(buf, n);

    due_us = hal_time_us() + SIGNING_MARGIN_US; /* the control tick is due before any hash ends */
    for (uint8_t k = 0; k < 5u; k++) {
        link_poll(s_now_ms);
    }
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(frames0, link_state()->rx_frames, "no hash without room");
    TEST_ASSERT_FALSE(link_state()->estop);

    /* room for 2 blocks of COMMAND_LONG + 2 of its signed COMMAND_ACK: one frame per call */
    due_us = hal_time_us() + 4u * SIGNING_BLOCK_US + SIGNING_MARGIN_US;
    link_poll(s_now_ms);
    TEST_ASSERT_EQUAL_UINT16(frames0 + 1u, link_state()->rx_frames);
    TEST_ASSERT_TRUE_MESSAGE(link_state()->estop, "first frame first");
    link_poll(s_now_ms);
    TEST_ASSERT_EQUAL_UINT16(frames0 + 2u, link_state()->rx_frames);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->estop, "then the second");
    TEST_ASSERT_EQUAL_UINT16(0u, link_state()->rx_unsigned + link_state()->rx_bad_signature + link_state()->rx_replay);

    /* never room: the frame goes through after a bounded wait rather than block the link */
    n = estop_frame(KEY, T0 + 300u, 1.0f, buf);
    wire_put(buf, n);
    due_us = hal_time_us();
    for (uint8_t k = 0; k < 20u && !link_state()->estop; k++) {
        link_poll(s_now_ms);
    }
    TEST_ASSERT_TRUE_MESSAGE(link_state()->estop, "taken after the bounded wait");
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_sha256_matches_fips_examples);
    RUN_TEST(test_signing_off_without_key_accepts_unsigned);
    RUN_TEST(test_signing_unsigned_key_in_provisioning_window_is_set);
    RUN_TEST(test_signing_unsigned_key_after_window_is_refused);
    RUN_TEST(test_signing_no_window_after_watchdog_boot);
    RUN_TEST(test_signing_with_key_rejects_and_counts_unsigned);
    RUN_TEST(test_signing_with_key_accepts_correctly_signed);
    RUN_TEST(test_signing_with_key_rejects_and_counts_wrong_key);
    RUN_TEST(test_signing_replayed_frame_is_rejected_and_counted);
    RUN_TEST(test_signing_frame_older_than_a_minute_from_a_new_stream_is_rejected);
    RUN_TEST(test_signing_key_change_signed_with_current_key_is_accepted_after_window);
    RUN_TEST(test_signing_zero_key_signed_clears_signing);
    RUN_TEST(test_signing_key_survives_reboot_via_eeprom);
    RUN_TEST(test_signing_corrupt_key_record_fails_closed);
    RUN_TEST(test_signing_key_change_cut_short_leaves_a_whole_key);
    RUN_TEST(test_signing_timestamp_is_stored_and_restored_ahead_after_reboot);
    RUN_TEST(test_signing_robot_signs_its_telemetry);
    RUN_TEST(test_signing_telemetry_unsigned_when_off_but_commands_still_verified);
    RUN_TEST(test_signing_frame_waits_for_room_before_control_tick_then_is_handled_in_order);
    return UNITY_END();
}
