#include "signing.h"

#include <string.h>

#include "crc16.h"
#include "hal.h"
#include "storage.h"

static mavlink_signing_t s_sign;
static mavlink_signing_streams_t s_streams;
static mavlink_status_t *s_rx;
static mavlink_status_t *s_tx;
static uint8_t s_state;
static uint64_t s_saved_ts;  /* newest timestamp stored or being stored (or the boot value) */
static uint32_t s_last_ms;
static uint8_t s_ts_slot;    /* slot the next timestamp goes to */
static bool s_provisioning;
static bool s_sign_telemetry; /* sent frames signed while a key is set */
/* Timestamp writer: one slot, one byte per tick while the EEPROM is free (the key record is
 * lib/storage's). */
static bool s_ts_writing;
static uint8_t s_wr_pos;
static uint16_t s_wr_crc;

/* Timestamp bytes in EEPROM are little-endian, as every target stores a uint64_t: a copy of
 * its first 6 bytes is the record (no 64-bit shifts). */
_Static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "timestamp record = the low 6 bytes in memory");

static bool accept_unsigned(const mavlink_status_t *status, uint32_t msgid)
{
    (void)status;
    return signing_accept_unsigned(msgid);
}

bool signing_accept_unsigned(uint32_t msgid)
{
    return msgid == MAVLINK_MSG_ID_RADIO_STATUS || (s_provisioning && msgid == MAVLINK_MSG_ID_SETUP_SIGNING);
}

void signing_set_provisioning(bool open) { s_provisioning = open; }

static void attach(bool on)
{
    s_rx->signing = on ? &s_sign : 0;
    s_rx->signing_streams = on ? &s_streams : 0;
    s_tx->signing = on && s_sign_telemetry ? &s_sign : 0;
    s_tx->signing_streams = on && s_sign_telemetry ? &s_streams : 0;
}

void signing_set_sign_telemetry(bool on)
{
    if (on != s_sign_telemetry) {
        s_sign_telemetry = on;
        attach(s_state != SIGNING_OFF);
    }
}

static bool key_is_zero(const uint8_t *k)
{
    uint8_t acc = 0u;
    for (uint8_t i = 0; i < 32u; i++) {
        acc |= k[i];
    }
    return acc == 0u;
}

#define KEY_ERASED 3u /* load_key_at(): the slot was never written */

/* SIGNING_ON or SIGNING_OFF (a whole record; an all-zero key is "off"), KEY_ERASED or SIGNING_KEY_CORRUPT. */
static uint8_t load_key_at(uint16_t addr)
{
    uint8_t rec[SIGNING_KEY_RECORD_BYTES];
    hal_eeprom_read(addr, rec, sizeof rec);
    memcpy(s_sign.secret_key, &rec[2], 32u);
    uint8_t all = 0xFFu;
    for (uint8_t i = 0; i < sizeof rec; i++) {
        all &= rec[i];
    }
    if (all == 0xFFu) {
        return KEY_ERASED;
    }
    if ((uint16_t)(rec[0] | ((uint16_t)rec[1] << 8)) != SIGNING_MAGIC || !storage_slot_ok(addr, sizeof rec)) {
        return SIGNING_KEY_CORRUPT;
    }
    return key_is_zero(s_sign.secret_key) ? SIGNING_OFF : SIGNING_ON;
}

/* The main slot when it holds a whole record, else a whole copy (a key change cut short by a power
 * cut), else the main slot's verdict: erased = no key, damaged = fail closed. */
static uint8_t load_key(void)
{
    uint8_t st = load_key_at(SIGNING_KEY_ADDR);
    if (st <= SIGNING_ON) {
        return st;
    }
    uint8_t copy = load_key_at(SIGNING_KEY_COPY_ADDR);
    if (copy <= SIGNING_ON) {
        return copy;
    }
    return st == KEY_ERASED ? SIGNING_OFF : SIGNING_KEY_CORRUPT;
}

/* Boot only. Not inlined: its 64-bit comparisons stay out of agnav_setup() (LTO). */
__attribute__((noinline)) static void load_timestamp(void)
{
    uint64_t best = 0u;
    uint8_t best_slot = SIGNING_TS_SLOTS - 1u;
    for (uint8_t i = 0; i < SIGNING_TS_SLOTS; i++) {
        uint8_t rec[SIGNING_TS_SLOT_BYTES];
        hal_eeprom_read((uint16_t)(SIGNING_TS_ADDR + i * SIGNING_TS_SLOT_BYTES), rec, sizeof rec);
        uint16_t crc = (uint16_t)(rec[6] | ((uint16_t)rec[7] << 8));
        if (crc != crc16_ccitt_false(rec, 6u)) {
            continue;
        }
        uint64_t ts = 0u;
        memcpy(&ts, rec, 6u);
        if (ts >= best) {
            best = ts;
            best_slot = i;
        }
    }
    s_ts_slot = (uint8_t)((best_slot + 1u) % SIGNING_TS_SLOTS);
    s_saved_ts = best + SIGNING_TS_SAVE_INTERVAL;
    s_sign.timestamp = s_saved_ts;
}

void signing_init(mavlink_status_t *rx, mavlink_status_t *tx, uint32_t now_ms)
{
    memset(&s_sign, 0, sizeof s_sign);
    memset(&s_streams, 0, sizeof s_streams);
    s_rx = rx;
    s_tx = tx;
    s_ts_writing = false;
    s_sign_telemetry = true;
    s_last_ms = now_ms;
    s_state = load_key();
    load_timestamp();
    s_sign.accept_unsigned_callback = accept_unsigned;
    s_sign.flags = MAVLINK_SIGNING_FLAG_SIGN_OUTGOING;
    attach(s_state != SIGNING_OFF);
}

uint8_t signing_state(void) { return s_state; }
uint64_t signing_timestamp(void) { return s_sign.timestamp; }
bool signing_write_pending(void) { return s_ts_writing || storage_pending(STORAGE_SIGNING_KEY); }

void signing_set_key(const uint8_t key[32], uint64_t initial_timestamp)
{
    memcpy(s_sign.secret_key, key, 32u);
    memset(&s_streams, 0, sizeof s_streams); /* streams seen under the old key start afresh */
    if (initial_timestamp > s_sign.timestamp) {
        s_sign.timestamp = initial_timestamp;
    }
    s_state = key_is_zero(key) ? SIGNING_OFF : SIGNING_ON;
    attach(s_state == SIGNING_ON);
    storage_request(STORAGE_SIGNING_KEY);
}

uint8_t signing_key_record_byte(uint16_t pos)
{
    return pos < 2u ? (uint8_t)(SIGNING_MAGIC >> (8u * pos)) : s_sign.secret_key[pos - 2u];
}

void signing_tick(uint32_t now_ms)
{
    uint32_t dt_ms = now_ms - s_last_ms;
    s_last_ms = now_ms;
    if (s_state == SIGNING_OFF && !s_ts_writing) {
        return;
    }
    s_sign.timestamp += (uint64_t)dt_ms * 100u;
    if (!s_ts_writing && s_state == SIGNING_ON && s_sign.timestamp >= s_saved_ts + SIGNING_TS_SAVE_INTERVAL) {
        s_saved_ts = s_sign.timestamp;
        s_wr_crc = crc16_ccitt_false(&s_saved_ts, 6u);
        s_ts_writing = true;
        s_wr_pos = 0u;
    }
    if (!s_ts_writing || hal_eeprom_busy()) {
        return;
    }
    uint8_t b = s_wr_pos < 6u ? ((const uint8_t *)&s_saved_ts)[s_wr_pos] : (uint8_t)(s_wr_crc >> (8u * (s_wr_pos - 6u)));
    (void)hal_eeprom_write_byte((uint16_t)(SIGNING_TS_ADDR + s_ts_slot * SIGNING_TS_SLOT_BYTES + s_wr_pos), b);
    if (++s_wr_pos >= SIGNING_TS_SLOT_BYTES) {
        s_ts_slot = (uint8_t)((s_ts_slot + 1u) % SIGNING_TS_SLOTS);
        s_ts_writing = false;
    }
}
