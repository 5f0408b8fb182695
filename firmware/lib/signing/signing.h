/*
 * MAVLink 2 message signing: the secret key and the signing timestamp, kept in
 * EEPROM, and the hooks that make the MAVLink library check every received frame
 * and sign every sent one while a key is set.
 *
 * Key record at SIGNING_KEY_ADDR, with a copy at SIGNING_KEY_COPY_ADDR (lib/storage writes the
 * copy first, then the main slot, so a power cut during a key change leaves one whole):
 *   0 magic u16 = SIGNING_MAGIC, 2 key[32], 34 crc16 (CRC-16/CCITT-FALSE of bytes 0..33)
 * The main slot is used when whole, else the copy. Both erased (0xFF), or an all-zero
 * key, means "no key": signing off, every frame accepted. Neither whole and the main one
 * not erased (damaged) FAILS CLOSED: signing stays on with that unusable key, so nothing
 * is accepted until a key is provisioned again (see link.h for how).
 *
 * Timestamp (MAVLink units: 10 us since 2015-01-01). The firmware has no clock of the
 * calendar; it starts from the newest stored value plus SIGNING_TS_SAVE_INTERVAL (the
 * most that may have passed unsaved), advances with hal time and jumps forward to any
 * newer timestamp of an accepted frame (done by the MAVLink library). It is stored when
 * it has moved SIGNING_TS_SAVE_INTERVAL past the last stored value, into a ring of
 * SIGNING_TS_SLOTS slots {timestamp u48, crc16} so each EEPROM cell sees 1/8 of the
 * writes (30 s interval: one write per cell every 4 min of signed operation, 100 000
 * cycles last ~9 months of continuous running). After a reboot, frames recorded more
 * than 60 s (MAVLINK_SIGNING_TIMESTAMP_LIMIT) before that start value are refused
 * as replays; see docs/safety.md for the window that remains.
 *
 * EEPROM writes never block the loop: a timestamp slot is written one byte per
 * signing_tick() call while hal_eeprom_busy() is false (an AVR EEPROM byte takes 3.3 ms).
 */
#ifndef AGNAV_SIGNING_H
#define AGNAV_SIGNING_H

#include <stdbool.h>
#include <stdint.h>

#include "mavlink_lib.h"
#include "params.h"

#define SIGNING_KEY_ADDR 0x0040u
#define SIGNING_KEY_COPY_ADDR 0x00B0u
#define SIGNING_KEY_RECORD_BYTES 36u
#define SIGNING_TS_ADDR 0x0070u
#define SIGNING_TS_SLOTS 8u
#define SIGNING_TS_SLOT_BYTES 8u
#define SIGNING_MAGIC 0x5349u                     /* "IS" */
#define SIGNING_TS_SAVE_INTERVAL 3000000ULL       /* 30 s in 10 us units */

/* Time of one 64-byte SHA-256 block on this target, with the interrupts that land in it
 * (agnav_sha256_block: 44 896 cycles = 2806 us at 16 MHz under simavr, +3 % for the encoder,
 * sonar and UART interrupts), and what the link task adds around a hash (parse, dispatch,
 * the sonar task that may run before the control tick). link.c starts a hash only when
 * blocks * SIGNING_BLOCK_US + SIGNING_MARGIN_US fit before the next control tick. */
#if defined(__AVR__)
#define SIGNING_BLOCK_US 2900u
#define SIGNING_MARGIN_US 700u
#else
#define SIGNING_BLOCK_US 20u
#define SIGNING_MARGIN_US 100u
#endif

typedef enum {
    SIGNING_OFF = 0,         /* no key: unsigned and signed frames accepted, nothing signed */
    SIGNING_ON = 1,          /* key set: only correctly signed, fresh frames accepted */
    SIGNING_KEY_CORRUPT = 2  /* stored record damaged: fail closed (nothing accepted) */
} signing_state_t;

/* Load key and timestamp from EEPROM and attach the signing state to the receive
 * status (frames checked) and the send status (frames signed). */
void signing_init(mavlink_status_t *rx, mavlink_status_t *tx, uint32_t now_ms);
uint8_t signing_state(void); /* signing_state_t */
/* Set (all-zero key: clear) the key, raise the timestamp to at least initial_timestamp,
 * and queue the key record's write (lib/storage, STORAGE_SIGNING_KEY). */
void signing_set_key(const uint8_t key[32], uint64_t initial_timestamp);
/* Byte pos (< SIGNING_KEY_RECORD_BYTES - 2) of the key record, for lib/storage. */
uint8_t signing_key_record_byte(uint16_t pos);
/* Advance the timestamp to now_ms and write at most one byte of a timestamp slot. */
void signing_tick(uint32_t now_ms);
uint64_t signing_timestamp(void);
bool signing_write_pending(void); /* a timestamp slot or the key record not yet written */
/* Frames without a signature that pass the parser even while signing is on: RADIO_STATUS
 * (radios inject it and cannot sign; the firmware does not act on it) and, only while the
 * provisioning window is open, SETUP_SIGNING (link.c decides whether to apply it). */
bool signing_accept_unsigned(uint32_t msgid);
void signing_set_provisioning(bool open);
/* Whether sent frames are signed while a key is set (parameter SIGN_TELEM; on after
 * signing_init()). Received frames are verified either way: only the robot's own
 * telemetry goes out unsigned when off (docs/safety.md "Signing"). Cheap, may be called
 * every link task. */
void signing_set_sign_telemetry(bool on);
/* The parameter (signing_params.c: SIGN_TELEM, 1 = sign). */
extern uint8_t signing_param_sign_telem;
extern const PARAMS_ROM param_group_t SIGNING_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

#endif
