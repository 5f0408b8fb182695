/*
 * Fuzz target: bytes on the host link UART of the whole firmware.
 *
 * The firmware (firmware/src/main.c and every firmware/lib module, unchanged) runs against the
 * simulated HAL through the SIL API (hil/sil/sil_api.c), exactly as in the native SIL. Each
 * input is one power-on:
 *   1. sil_reset(): time 0, erased EEPROM, empty UART queues, agnav_setup() (parameters,
 *      calibration, link and scheduler state re-initialised).
 *   2. The input is written to the link UART in chunks of 1..64 bytes; after each chunk the
 *      simulated clock moves on 1..3 ms (now and then 300 ms, past the link timeouts) and the
 *      firmware's main loop runs once, so the scheduler's link task parses the bytes and
 *      main.c's handlers (calibration, arming) and the control task act on them.
 *   3. 25 ms more of main loop at 1 ms ticks, so the 20 ms tasks (control, status) run
 *      on the final state.
 * The chunk sizes and time steps come from a small generator seeded with the input length, so
 * one input always replays the same way.
 *
 * Oracle, besides the sanitizers: everything the firmware sends back must be whole MAVLink
 * frames with a correct CRC (no torn frame, no stray byte); anything else calls abort().
 *
 * Three modes (fuzz_fix_crc; the libFuzzer build sets it with -DFUZZ_FIX_CRC=1 or 2, the replay
 * driver with --fix-crc or --sign):
 *   0  the bytes go to the firmware as they are: mutated frames mostly fail the CRC, so this
 *      mode tests the framing and the error counting;
 *   1  the harness first walks the input as the parser would and rewrites the CRC of every
 *      MAVLink 1 or 2 frame it describes (with the message's crc_extra), so mutated payloads
 *      reach the message decoders and handlers;
 *   2  signing on: after the power-on the firmware gets a key (signing_set_key), and every
 *      MAVLink 2 frame the input describes is re-emitted with the signed flag, its CRC and a
 *      valid signature block under that key (link id from the input, timestamps rising from
 *      FUZZ_SIGN_T0), so mutated payloads pass the signature check and reach the handlers with
 *      signing on (key changes, replay windows, signed answers); MAVLink 1 frames and the
 *      bytes between frames go through unchanged (and are refused as unsigned).
 * The same corpus and dictionary serve all modes.
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "fuzz_link.h"
#include "mavlink_lib.h"
#include "sil_api.h"
#include "signing.h"

#ifndef FUZZ_FIX_CRC
#define FUZZ_FIX_CRC 0
#endif

#define FUZZ_MAX_INPUT 4096u /* also the sim UART queue size: a chunk always fits */
#define FUZZ_SETTLE_MS 25u   /* final main-loop run: one control period and its telemetry */

int fuzz_fix_crc = FUZZ_FIX_CRC;

#define FUZZ_SIGN_T0 500000000000ULL /* signing timestamp of the first signed frame, 10 us units (~2016) */

static const uint8_t FUZZ_KEY[32] = {0x61, 0x67, 0x6e, 0x61, 0x76, 0x2d, 0x66, 0x75, 0x7a, 0x7a, 0x2d, 0x6b, 0x65, 0x79, 0x01, 0x02,
                                     0x03, 0x04, 0x05, 0x06, 0x07, 0x08, 0x09, 0x0a, 0x0b, 0x0c, 0x0d, 0x0e, 0x0f, 0x10, 0x11, 0x12};

static uint8_t s_buf[FUZZ_MAX_INPUT];
/* signed mode: each frame may grow by a signature block (13 bytes), at most one frame per 12 input bytes */
static uint8_t s_signed[FUZZ_MAX_INPUT + (FUZZ_MAX_INPUT / 12u + 1u) * MAVLINK_SIGNATURE_BLOCK_LEN];
static uint8_t s_tx[8192];
static mavlink_message_t s_out_msg;
static mavlink_status_t s_out_status;

/* xorshift32: chunk sizes and time steps, seeded from the input length only (so that a mutation
 * of a byte value does not also move the chunk boundaries). */
static uint32_t next_rand(uint32_t *s)
{
    uint32_t x = *s;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *s = x;
    return x;
}

static uint16_t frame_crc(const uint8_t *hdr, uint16_t hdr_len, const uint8_t *payload, uint8_t len, uint32_t msgid)
{
    const mavlink_msg_entry_t *e = mavlink_get_msg_entry(msgid);
    uint16_t crc = crc_calculate(hdr, hdr_len);
    crc_accumulate_buffer(&crc, (const char *)payload, len);
    crc_accumulate(e != NULL ? e->crc_extra : 0u, &crc);
    return crc;
}

/* Bytes of the whole MAVLink frame that starts at b[i] - a MAVLink 2 frame with its signature block
 * when flagged, or a MAVLink 1 frame - the way the parser reads it; 0 when none starts there or it
 * runs past n. */
static size_t frame_at(const uint8_t *b, size_t i, size_t n)
{
    size_t total = 0u;
    if (b[i] == MAVLINK_STX && i + MAVLINK_NUM_HEADER_BYTES <= n) {
        size_t sig = (b[i + 2] & MAVLINK_IFLAG_SIGNED) != 0u ? MAVLINK_SIGNATURE_BLOCK_LEN : 0u;
        total = MAVLINK_NUM_HEADER_BYTES + (size_t)b[i + 1] + MAVLINK_NUM_CHECKSUM_BYTES + sig;
    } else if (b[i] == MAVLINK_STX_MAVLINK1 && i + 6u <= n) {
        total = 6u + (size_t)b[i + 1] + MAVLINK_NUM_CHECKSUM_BYTES;
    }
    return i + total <= n ? total : 0u;
}

void fuzz_fix_frame_crcs(uint8_t *b, size_t n)
{
    size_t i = 0;
    while (i < n) {
        size_t total = frame_at(b, i, n);
        if (total == 0u) {
            i++;
            continue;
        }
        uint8_t len = b[i + 1];
        uint16_t crc;
        uint8_t *c;
        if (b[i] == MAVLINK_STX) {
            uint32_t msgid = (uint32_t)b[i + 7] | ((uint32_t)b[i + 8] << 8) | ((uint32_t)b[i + 9] << 16);
            crc = frame_crc(&b[i + 1], MAVLINK_CORE_HEADER_LEN, &b[i + MAVLINK_NUM_HEADER_BYTES], len, msgid);
            c = &b[i + MAVLINK_NUM_HEADER_BYTES + len];
        } else {
            crc = frame_crc(&b[i + 1], 5u, &b[i + 6], len, b[i + 5]);
            c = &b[i + 6u + len];
        }
        c[0] = (uint8_t)(crc & 0xFFu);
        c[1] = (uint8_t)(crc >> 8);
        i += total;
    }
}

size_t fuzz_sign_frames(const uint8_t *in, size_t n, uint8_t *out, size_t cap)
{
    mavlink_signing_t sign;
    memset(&sign, 0, sizeof sign);
    sign.flags = MAVLINK_SIGNING_FLAG_SIGN_OUTGOING;
    sign.timestamp = FUZZ_SIGN_T0;
    memcpy(sign.secret_key, FUZZ_KEY, sizeof FUZZ_KEY);
    size_t i = 0;
    size_t o = 0;
    while (i < n) {
        size_t total = frame_at(in, i, n);
        uint8_t len = total != 0u ? in[i + 1] : 0u;
        size_t grown = MAVLINK_NUM_HEADER_BYTES + (size_t)len + MAVLINK_NUM_CHECKSUM_BYTES + MAVLINK_SIGNATURE_BLOCK_LEN;
        if (total != 0u && in[i] == MAVLINK_STX && o + grown <= cap) {
            bool had_sig = (in[i + 2] & MAVLINK_IFLAG_SIGNED) != 0u;
            uint8_t *h = &out[o];
            memcpy(h, &in[i], MAVLINK_NUM_HEADER_BYTES + (size_t)len);
            h[2] |= MAVLINK_IFLAG_SIGNED;
            uint32_t msgid = (uint32_t)h[7] | ((uint32_t)h[8] << 8) | ((uint32_t)h[9] << 16);
            uint8_t *payload = &h[MAVLINK_NUM_HEADER_BYTES];
            uint16_t crc = frame_crc(&h[1], MAVLINK_CORE_HEADER_LEN, payload, len, msgid);
            uint8_t *c = &payload[len];
            c[0] = (uint8_t)(crc & 0xFFu);
            c[1] = (uint8_t)(crc >> 8);
            /* the input's own first signature byte (if it has one) picks the link id */
            sign.link_id = had_sig ? in[i + MAVLINK_NUM_HEADER_BYTES + len + MAVLINK_NUM_CHECKSUM_BYTES] : 0u;
            (void)mavlink_sign_packet(&sign, &c[2], h, MAVLINK_NUM_HEADER_BYTES, payload, len, c);
            o += grown;
            i += total;
            continue;
        }
        if (o >= cap) {
            break;
        }
        out[o++] = in[i++];
    }
    return o;
}

/* The firmware's output must parse as whole, valid frames. */
static void check_output(void)
{
    uint32_t n;
    while ((n = sil_uart_read(s_tx, sizeof s_tx)) > 0u) {
        for (uint32_t k = 0; k < n; k++) {
            uint8_t r = mavlink_frame_char_buffer(&s_out_msg, &s_out_status, s_tx[k], NULL, NULL);
            if (r == MAVLINK_FRAMING_BAD_CRC || r == MAVLINK_FRAMING_BAD_SIGNATURE) {
                abort(); /* the firmware sent a frame that does not check */
            }
            if (s_out_status.parse_state <= MAVLINK_PARSE_STATE_IDLE && r != MAVLINK_FRAMING_OK) {
                abort(); /* a byte outside any frame */
            }
        }
    }
    if (s_out_status.parse_state > MAVLINK_PARSE_STATE_IDLE) {
        abort(); /* a frame cut short: the queue held only part of it */
    }
}

static void run_ms(uint32_t ms, uint32_t tick_us)
{
    sil_set_tick_us(tick_us);
    (void)sil_step(ms * 1000u);
    check_output();
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > FUZZ_MAX_INPUT) {
        return -1; /* not added to the corpus */
    }
    const uint8_t *in = s_buf;
    memcpy(s_buf, data, size);
    if (fuzz_fix_crc == 1) {
        fuzz_fix_frame_crcs(s_buf, size);
    } else if (fuzz_fix_crc == 2) {
        size = fuzz_sign_frames(data, size, s_signed, sizeof s_signed);
        in = s_signed;
    }

    sil_reset();
    sil_set_stop_on_trigger(0);
    if (fuzz_fix_crc == 2) {
        signing_set_key(FUZZ_KEY, FUZZ_SIGN_T0);
    }
    memset(&s_out_status, 0, sizeof s_out_status);
    check_output(); /* boot messages (STATUSTEXT about defaults) */

    uint32_t seed = 0x9E3779B9u ^ (uint32_t)size;
    size_t i = 0;
    while (i < size) {
        uint32_t r = next_rand(&seed);
        size_t chunk = 1u + (r & 63u);
        if (chunk > size - i) {
            chunk = size - i;
        }
        (void)sil_uart_write(&in[i], (uint32_t)chunk);
        i += chunk;
        uint32_t step_ms = ((r >> 8) & 15u) == 0u ? 300u : 1u + ((r >> 12) % 3u);
        /* One main-loop pass per chunk (the tick is the whole step), except for the long pauses. */
        run_ms(step_ms, step_ms > 10u ? 10000u : step_ms * 1000u);
    }
    run_ms(FUZZ_SETTLE_MS, 1000u);
    return 0;
}
