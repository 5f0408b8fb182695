/* Fuzz target of the host link (see fuzz_link.c). */
#ifndef AGNAV_FUZZ_LINK_H
#define AGNAV_FUZZ_LINK_H

#include <stddef.h>
#include <stdint.h>

/* 1: rewrite the CRC of every frame the input describes before feeding it (deep mode). */
extern int fuzz_fix_crc;

/* Rewrite, in place, the CRC of each MAVLink 1/2 frame found in b[0..n) the way the parser walks. */
void fuzz_fix_frame_crcs(uint8_t *b, size_t n);

/* libFuzzer's entry point: one power-on of the firmware fed with data. Returns 0, or -1 for an
 * input longer than the harness takes. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

#endif
