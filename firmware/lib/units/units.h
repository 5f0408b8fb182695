/*
 * Integer unit helpers shared by firmware modules (header only, no state).
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

/* Speed and distance conversions (exact integer scale factors). */
static inline int32_t units_mm_from_cm(int32_t cm) { return cm * 10L; }
static inline int32_t units_um_from_mm(int32_t mm) { return mm * 1000L; }

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_UNITS_H */
