/*
 * Integer unit helpers shared by firmware modules (no state; units.c holds the one not inlined).
 *
 * Firmware quantities are suffixed integers: _um, _mm, _mm_s, _cdeg,
 * _cdeg_s, _us, _ms. Helpers here are exact for the documented input ranges
 * and avoid 32-bit division, which costs ~600 cycles on the AVR.
 */
#ifndef AGNAV_UNITS_H
#define AGNAV_UNITS_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Read-only lookup tables: on avr-gcc the __flash address space keeps them in
 * program memory (otherwise every const array is copied into the 8 KB RAM);
 * elsewhere it is plain const. Data declared UNITS_ROM must be read directly
 * (t[i], struct copy), never through a generic pointer. */
#if defined(__AVR__) && defined(__FLASH)
#define UNITS_ROM __flash
#else
#define UNITS_ROM
#endif

#define UNITS_CDEG_PER_TURN 36000L
#define UNITS_CDEG_HALF_TURN 18000L

/* Wrap any centidegree angle into (-18000, 18000]. */
static inline int32_t units_wrap_cdeg(int32_t a_cdeg)
{
    a_cdeg %= UNITS_CDEG_PER_TURN; /* now in (-36000, 36000) */
    if (a_cdeg > UNITS_CDEG_HALF_TURN) {
        a_cdeg -= UNITS_CDEG_PER_TURN;
    } else if (a_cdeg <= -UNITS_CDEG_HALF_TURN) {
        a_cdeg += UNITS_CDEG_PER_TURN;
    }
    return a_cdeg;
}

/* Floor division by 1000 without a division instruction, for
 * |t| < 2^20 (~1.05e6): returns q = floor(t / 1000) and stores
 * t - 1000*q (0..999) in *rem. Used to carry micrometres into millimetres.
 * 1049 / 2^20 overestimates 1/1000 by 4e-4, so the first guess is off by
 * at most one in either direction; the two fix-up steps correct it. */
static inline int32_t units_floordiv1000(int32_t t, int16_t *rem)
{
    int32_t q = (t * 1049L) >> 20; /* arithmetic shift: floor for negatives (gcc) */
    int32_t r = t - q * 1000L;
    while (r < 0) {
        q--;
        r += 1000L;
    }
    while (r >= 1000L) {
        q++;
        r -= 1000L;
    }
    *rem = (int16_t)r;
    return q;
}

/* |v| as unsigned: defined for INT32_MIN too (2^31), where -v would overflow. The one abs of the
 * firmware (an absolute difference: units_abs_u32((int32_t)a - b)). */
static inline uint32_t units_abs_u32(int32_t v) { return v < 0 ? 0u - (uint32_t)v : (uint32_t)v; }

/* The rounding division of the firmware: n / d to the nearest integer, halves up (d > 0, n + d / 2
 * within 32 bits). */
static inline uint32_t units_div_round_u32(uint32_t n, uint32_t d) { return (n + d / 2u) / d; }

/* The same with halves away from zero, for a signed n (d > 0, |n| + d / 2 within 32 bits; one
 * division: C's truncates toward zero). */
static inline int32_t units_div_round_i32(int32_t n, int32_t d) { return (n >= 0 ? n + d / 2 : n - d / 2) / d; }

/* The same in 64 bits (d > 0, n + d / 2 within 64 bits): configuration, and the rare wide case of a
 * speed estimate. Not inlined (units.c): on the AVR 64-bit division is a library call with a long
 * argument setup, written out once. */
uint64_t units_div_round_u64(uint64_t n, uint64_t d);

/* Speed and distance conversions (exact integer scale factors). */
static inline int32_t units_mm_from_cm(int32_t cm) { return cm * 10L; }
static inline int32_t units_um_from_mm(int32_t mm) { return mm * 1000L; }

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_UNITS_H */
