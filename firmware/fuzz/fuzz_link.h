/* Fuzz target of the host link (see fuzz_link.c). */
#ifndef AGNAV_FUZZ_LINK_H
#define AGNAV_FUZZ_LINK_H

#include <stddef.h>
#include <stdint.h>

/* 1: rewrite the CRC of every frame the input describes before feeding it (deep mode);
 * 2: signing on, every MAVLink 2 frame re-emitted signed under the harness's key (fuzz_link.c). */
extern int fuzz_fix_crc;

/* Copy in[0..n) to out (capacity cap) with every MAVLink 2 frame it describes signed (flag, CRC,
 * signature block under the harness's key, rising timestamps); returns the bytes written. */
size_t fuzz_sign_frames(const uint8_t *in, size_t n, uint8_t *out, size_t cap);

/* Rewrite, in place, the CRC of each MAVLink 1/2 frame found in b[0..n) the way the parser walks. */
void fuzz_fix_frame_crcs(uint8_t *b, size_t n);

/* libFuzzer's entry point: one power-on of the firmware fed with data. Returns 0, or -1 for an
 * input longer than the harness takes. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#endif
