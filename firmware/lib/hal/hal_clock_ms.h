/*
 * Milliseconds from the HAL's 32-bit microsecond clock, counting on across its wrap.
 *
 * The microsecond clock wraps every 2^32 us (71.6 min). Milliseconds derived as us / 1000 would
 * jump back to 0 there, and every "now_ms - then_ms" in the firmware (link and setpoint timeouts,
 * stuck-wheel checks, canyon timers, the signing timestamp) would read an elapsed time of 49 days.
 * This clock adds the microseconds elapsed since the last reading instead, so milliseconds wrap
 * only at 2^32 ms (49.7 days), like the STM32's SysTick counter.
 *
 * Cheap on an 8-bit core: callers ask every few ms, so the elapsed microseconds fit 16 bits and a
 * short multiply replaces libgcc's 32-bit division (~650 cycles); a longer gap takes the division
 * once. Loop side only (not for ISRs).
 */
#ifndef AGNAV_HAL_CLOCK_MS_H
#define AGNAV_HAL_CLOCK_MS_H

#include <stdint.h>

typedef struct {
    uint32_t ms; /* milliseconds so far */
    uint32_t us; /* the microsecond-clock reading that ms corresponds to (mod 2^32) */
} hal_clock_ms_t;

/* Start at the microsecond reading now_us (ms = now_us / 1000). */
static inline void hal_clock_ms_start(hal_clock_ms_t *c, uint32_t now_us)
{
    c->ms = now_us / 1000u;
    c->us = c->ms * 1000u;
}

/* Milliseconds at the microsecond reading now_us (readings must come at least once per 71 min). */
static inline uint32_t hal_clock_ms_update(hal_clock_ms_t *c, uint32_t now_us)
{
    uint32_t d = now_us - c->us; /* modulo 2^32: right across the clock's wrap */
    if (d > 0xFFFFu) {           /* a long gap: the rare 32-bit division */
        uint32_t q = d / 1000u;
        c->ms += q;
        c->us += q * 1000u;
        d -= q * 1000u;
    }
    /* d * 65 / 2^16 is d / 1000 or one less for any 16-bit d (65 / 2^16 is 0.8 % under 1 / 1000:
     * at most 0.54 under); the remainder check adds the one. The >> 16 is a register move. */
    uint16_t d_us = (uint16_t)d;
    uint16_t q = (uint16_t)(((uint32_t)d_us * 65u) >> 16);
    if ((uint16_t)(d_us - q * 1000u) >= 1000u) {
        q++;
    }
    c->ms += q;
    c->us += (uint32_t)q * 1000u;
    return c->ms;
}

#endif
