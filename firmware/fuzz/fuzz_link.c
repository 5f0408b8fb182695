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
 * Two modes (fuzz_fix_crc; the libFuzzer build sets it with -DFUZZ_FIX_CRC=1, the replay
 * driver with --fix-crc):
 *   0  the bytes go to the firmware as they are: mutated frames mostly fail the CRC, so this
 *      mode tests the framing and the error counting;
 *   1  the harness first walks the input as the parser would and rewrites the CRC of every
 *      MAVLink 1 or 2 frame it describes (with the message's crc_extra), so mutated payloads
 *      reach the message decoders and handlers.
 * The same corpus and dictionary serve both modes.
 */
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include <agnav_mavlink.h>

#include "fuzz_link.h"
#include "sil_api.h"

#ifndef FUZZ_FIX_CRC
#define FUZZ_FIX_CRC 0
#endif

#define FUZZ_MAX_INPUT 4096u /* also the sim UART queue size: a chunk always fits */
#define FUZZ_SETTLE_MS 25u   /* final main-loop run: one control period and its telemetry */

int fuzz_fix_crc = FUZZ_FIX_CRC;

static uint8_t s_buf[FUZZ_MAX_INPUT];
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

void fuzz_fix_frame_crcs(uint8_t *b, size_t n)
{
    size_t i = 0;
    while (i < n) {
        if (b[i] == MAVLINK_STX && i + MAVLINK_NUM_HEADER_BYTES <= n) {
            uint8_t len = b[i + 1];
            size_t sig = (b[i + 2] & MAVLINK_IFLAG_SIGNED) != 0u ? MAVLINK_SIGNATURE_BLOCK_LEN : 0u;
            size_t total = MAVLINK_NUM_HEADER_BYTES + (size_t)len + MAVLINK_NUM_CHECKSUM_BYTES + sig;
            if (i + total <= n) {
                uint32_t msgid = (uint32_t)b[i + 7] | ((uint32_t)b[i + 8] << 8) | ((uint32_t)b[i + 9] << 16);
                uint16_t crc =
                    frame_crc(&b[i + 1], MAVLINK_CORE_HEADER_LEN, &b[i + MAVLINK_NUM_HEADER_BYTES], len, msgid);
                b[i + MAVLINK_NUM_HEADER_BYTES + len] = (uint8_t)(crc & 0xFFu);
                b[i + MAVLINK_NUM_HEADER_BYTES + len + 1u] = (uint8_t)(crc >> 8);
                i += total;
                continue;
            }
        } else if (b[i] == MAVLINK_STX_MAVLINK1 && i + 6u <= n) {
            uint8_t len = b[i + 1];
            size_t total = 6u + (size_t)len + MAVLINK_NUM_CHECKSUM_BYTES;
            if (i + total <= n) {
                uint16_t crc = frame_crc(&b[i + 1], 5u, &b[i + 6], len, b[i + 5]);
                b[i + 6u + len] = (uint8_t)(crc & 0xFFu);
                b[i + 6u + len + 1u] = (uint8_t)(crc >> 8);
                i += total;
                continue;
            }
        }
        i++;
    }
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
    memcpy(s_buf, data, size);
    if (fuzz_fix_crc) {
        fuzz_fix_frame_crcs(s_buf, size);
    }

    sil_reset();
    sil_set_stop_on_trigger(0);
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
        (void)sil_uart_write(&s_buf[i], (uint32_t)chunk);
        i += chunk;
        uint32_t step_ms = ((r >> 8) & 15u) == 0u ? 300u : 1u + ((r >> 12) % 3u);
        /* One main-loop pass per chunk (the tick is the whole step), except for the long pauses. */
        run_ms(step_ms, step_ms > 10u ? 10000u : step_ms * 1000u);
    }
    run_ms(FUZZ_SETTLE_MS, 1000u);
    return 0;
}
