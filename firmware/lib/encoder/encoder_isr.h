/*
 * The encoder interrupt step, as an inline function so a board's pin-change
 * ISR can have it compiled in place (hal/avr does) instead of paying for a
 * call that saves every call-clobbered register. Everything else goes through
 * encoder.h; only ISRs include this file.
 *
 * The ISR record is lean on purpose: 16-bit counters (count, edges, errors)
 * that encoder_update()/encoder_snapshot() extend to 32 bits in the loop, which
 * they must call at least once per 32767 edges (0.8 s at 40 kHz; the 50 Hz
 * control task does), and the last two edge times for the period method.
 */
#ifndef AGNAV_ENCODER_ISR_H
#define AGNAV_ENCODER_ISR_H

#include <stdint.h>

#include "encoder.h"

#define ENCODER_QERR 2 /* table entry: both lines changed, direction unknown */

typedef struct {
    uint16_t count;        /* wraps; extended by the loop side (two's complement view) */
    uint16_t edges;        /* every hook call */
    uint16_t errors;       /* illegal quadrature jumps */
    uint32_t last_edge_us; /* time of the last counted step */
    uint32_t prev_edge_us; /* the one before, same direction; == last when unknown */
    const int8_t *table;   /* quadrature decode table (fwd / inverted), NULL in Hall mode */
    uint8_t ab;            /* last levels, (A << 1) | B */
    int8_t dir;            /* sign of the last counted step, 0 = none yet */
    int8_t hint;           /* Hall mode: sign applied to each pulse (already inverted) */
} encoder_isr_t;

extern encoder_isr_t encoder_isr_state[ENCODER_MAX];

/* One edge on encoder e: levels ab after the edge, time t_us. */
static inline __attribute__((always_inline)) void encoder_isr_step(encoder_isr_t *e, uint8_t ab, uint32_t t_us)
{
    uint8_t old = e->ab;
    e->ab = ab;
    e->edges++;
    int8_t step;
    if (e->table != 0) {
        step = e->table[(uint8_t)((uint8_t)(old << 2) | ab)];
        if (step == 0) {
            return; /* same levels again: no motion */
        }
        if (step == ENCODER_QERR) {
            e->errors++;
            return;
        }
    } else {
        /* Hall: count the rising edge of A only (one count per pulse). */
        if ((ab & 2u) == 0u || (old & 2u) != 0u) {
            return;
        }
        step = e->hint;
    }
    if (step > 0) {
        e->count++;
    } else {
        e->count--;
    }
    if (step == e->dir) {
        e->prev_edge_us = e->last_edge_us;
    } else {
        e->dir = step;
        e->prev_edge_us = t_us; /* direction changed or first count: period unknown */
    }
    e->last_edge_us = t_us;
}

#endif
