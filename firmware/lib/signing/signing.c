#include "signing.h"

#include <string.h>

#include "crc16.h"
#include "hal.h"

static mavlink_signing_t s_sign;
static mavlink_signing_streams_t s_streams;
static mavlink_status_t *s_rx;
static mavlink_status_t *s_tx;
static uint8_t s_state;
static uint64_t s_saved_ts;  /* newest timestamp stored (or the boot value) */
static uint32_t s_last_ms;
static uint8_t s_last_write_ms;
static uint8_t s_ts_slot;    /* slot the next timestamp goes to */
static bool s_provisioning;
static bool s_sign_telemetry; /* sent frames signed while a key is set */
/* Background writer: one record at a time, one byte per tick. */
static uint8_t s_wr_kind;    /* 0 none, 1 key record, 2 timestamp slot */
static uint8_t s_wr_pos;
static uint16_t s_wr_crc;
static uint64_t s_wr_ts;

enum { WR_NONE = 0, WR_KEY = 1, WR_TS = 2 };

/* Timestamp bytes in EEPROM are little-endian, as every target stores a uint64_t: a copy of
 * its first 6 bytes is the record (no 64-bit shifts, ~0.2 KB of AVR code). */
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

static uint16_t key_crc(const uint8_t *key)
{
    uint16_t magic = SIGNING_MAGIC;
    uint16_t crc = crc16_ccitt_false_update(CRC16_CCITT_FALSE_INIT, &magic, sizeof magic);
    return crc16_ccitt_false_update(crc, key, 32u);
}

static uint8_t load_key(void)
{
    uint16_t magic, crc;
    hal_eeprom_read(SIGNING_KEY_ADDR, &magic, sizeof magic);
    hal_eeprom_read(SIGNING_KEY_ADDR + 2u, s_sign.secret_key, 32u);
    hal_eeprom_read(SIGNING_KEY_ADDR + 34u, &crc, sizeof crc);
    uint8_t all = (uint8_t)(magic & (magic >> 8) & crc & (crc >> 8));
    for (uint8_t i = 0; i < 32u; i++) {
        all &= s_sign.secret_key[i];
    }
    if (all == 0xFFu) {
        return SIGNING_OFF; /* erased */
    }
    if (magic != SIGNING_MAGIC || crc != key_crc(s_sign.secret_key)) {
        return SIGNING_KEY_CORRUPT;
    }
    return key_is_zero(s_sign.secret_key) ? SIGNING_OFF : SIGNING_ON;
}

/* Boot only. Not inlined: its 64-bit comparisons written out in agnav_setup() (LTO) cost ~0.2 KB
 * more flash on the AVR. */
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
    s_wr_kind = WR_NONE;
    s_sign_telemetry = true;
    s_last_ms = now_ms;
    s_last_write_ms = (uint8_t)now_ms;
    s_state = load_key();
    load_timestamp();
    s_sign.accept_unsigned_callback = accept_unsigned;
    s_sign.flags = MAVLINK_SIGNING_FLAG_SIGN_OUTGOING;
    attach(s_state != SIGNING_OFF);
}

uint8_t signing_state(void) { return s_state; }
uint64_t signing_timestamp(void) { return s_sign.timestamp; }
bool signing_write_pending(void) { return s_wr_kind != WR_NONE; }

void signing_set_key(const uint8_t key[32], uint64_t initial_timestamp)
{
    memcpy(s_sign.secret_key, key, 32u);
    memset(&s_streams, 0, sizeof s_streams); /* streams seen under the old key start afresh */
    if (initial_timestamp > s_sign.timestamp) {
        s_sign.timestamp = initial_timestamp;
    }
    s_state = key_is_zero(key) ? SIGNING_OFF : SIGNING_ON;
    attach(s_state == SIGNING_ON);
    s_wr_kind = WR_KEY; /* replaces a timestamp write in progress: that slot's CRC fails, others hold */
    s_wr_pos = 0u;
    s_wr_crc = key_crc(key);
}

/* Byte pos of the record being written. */
static uint8_t record_byte(uint8_t pos)
{
    if (s_wr_kind == WR_KEY) {
        if (pos < 2u) {
            return (uint8_t)(SIGNING_MAGIC >> (8u * pos));
        }
        if (pos < 34u) {
            return s_sign.secret_key[pos - 2u];
        }
        return (uint8_t)(s_wr_crc >> (8u * (pos - 34u)));
    }
    if (pos < 6u) {
        return ((const uint8_t *)&s_wr_ts)[pos];
    }
    return (uint8_t)(s_wr_crc >> (8u * (pos - 6u)));
}

void signing_tick(uint32_t now_ms)
{
    uint32_t dt_ms = now_ms - s_last_ms;
    s_last_ms = now_ms;
    if (s_state == SIGNING_OFF && s_wr_kind == WR_NONE) {
        return;
    }
    s_sign.timestamp += (uint64_t)dt_ms * 100u;
    if (s_wr_kind == WR_NONE && s_state == SIGNING_ON && s_sign.timestamp >= s_saved_ts + SIGNING_TS_SAVE_INTERVAL) {
        s_wr_ts = s_sign.timestamp;
        s_wr_crc = crc16_ccitt_false(&s_wr_ts, 6u);
        s_wr_kind = WR_TS;
        s_wr_pos = 0u;
    }
    if (s_wr_kind == WR_NONE || (uint8_t)((uint8_t)now_ms - s_last_write_ms) < SIGNING_WRITE_GAP_MS) {
        return;
    }
    s_last_write_ms = (uint8_t)now_ms;
    uint8_t b = record_byte(s_wr_pos);
    uint16_t addr = s_wr_kind == WR_KEY ? (uint16_t)(SIGNING_KEY_ADDR + s_wr_pos)
                                        : (uint16_t)(SIGNING_TS_ADDR + s_ts_slot * SIGNING_TS_SLOT_BYTES + s_wr_pos);
    hal_eeprom_write(addr, &b, 1u);
    s_wr_pos++;
    uint8_t len = s_wr_kind == WR_KEY ? SIGNING_KEY_RECORD_BYTES : SIGNING_TS_SLOT_BYTES;
    if (s_wr_pos >= len) {
        if (s_wr_kind == WR_TS) {
            s_saved_ts = s_wr_ts;
            s_ts_slot = (uint8_t)((s_ts_slot + 1u) % SIGNING_TS_SLOTS);
        }
        s_wr_kind = WR_NONE;
    }
}
