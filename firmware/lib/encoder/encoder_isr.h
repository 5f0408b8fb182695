/*
 * The encoder interrupt record: what an edge handler writes and nothing more.
 * Three writers keep it, with identical rules:
 *   - encoder_isr_edge() (encoder.c), the generic hal_encoder_edge_fn hook of the
 *     sim and STM32 backends;
 *   - the ATmega2560's PORTK pin-change vector, hand-written in assembly
 *     (hal/avr/encoder_pcint_avr.S), which decodes all four encoders in one vector;
 *   - hal_encoder_poll() of the STM32 backend, in loop context, for wheels its timers
 *     count in encoder mode: the counter's step since the last poll, stamped with the
 *     poll time (no illegal jumps: errors stays 0).
 * The loop side (encoder_update(), encoder_snapshot()) folds the record into
 * 32-bit counts, travel, times and speed; only it knows modes, inversion and
 * the Hall direction hint.
 *
 * Decoding, per encoder, with ab = (A << 1) | B on every change of A or B:
 *   - both lines changed: illegal jump, errors += 1, nothing else;
 *   - one line changed: a step. It is raw-forward when A_new != B_old (the
 *     sequence 00 -> 10 -> 11 -> 01 -> 00, A leading B), raw-backward otherwise.
 *     A raw-forward step adds one to fwd and stores the time in fwd_stamp, a
 *     raw-backward step likewise to back / back_stamp;
 *   - no line changed (a repeated call): ignored.
 * A Hall sensor drives A only (B is constant): with B = 0 each rising edge is a
 * raw-forward step and each falling edge a raw-backward one (with B = 1, the
 * reverse), so fwd counts one edge per pulse and the loop signs it with the hint.
 *
 * Stamps are the low 16 bits of the time in 4 us units (t_us >> 2, which on the
 * AVR is Timer5's TCNT5 itself); the loop extends them to 32-bit microseconds,
 * which is exact as long as it folds the record at least every 262 ms while the
 * wheel turns (the 50 Hz update does). Counters are 16 bit and wrap; the loop
 * must fold at least every 32767 steps (0.8 s at 40 kHz).
 *
 * Carry rule: when a step carries the low byte of fwd (or back) to 0, the
 * handler increments the high byte and does NOT store the stamp (that keeps the
 * AVR vector under 60 cycles on every path). The loop knows: a stamp belongs to
 * the step that left the counter at (counter - 1) when the counter's low byte is
 * 0, else to the counter itself.
 */
#ifndef AGNAV_ENCODER_ISR_H
#define AGNAV_ENCODER_ISR_H

#define ENCODER_STAMP_SHIFT 2u /* stamp unit = 4 us */

#define ENCODER_ISR_SIZE 10
#define ENCODER_ISR_OFS_FWD 0
#define ENCODER_ISR_OFS_BACK 2
#define ENCODER_ISR_OFS_ERRORS 4
#define ENCODER_ISR_OFS_FWD_STAMP 6
#define ENCODER_ISR_OFS_BACK_STAMP 8

#ifndef __ASSEMBLER__
#include <stdint.h>

#include "encoder.h"

/* Layout fixed: the AVR vector addresses the fields by byte offset (ENCODER_ISR_OFS_*). */
typedef struct {
    uint16_t fwd;        /* raw-forward steps, wraps */
    uint16_t back;       /* raw-backward steps, wraps */
    uint16_t errors;     /* illegal jumps, wraps */
    uint16_t fwd_stamp;  /* (t_us >> 2) of the last stamped raw-forward step */
    uint16_t back_stamp; /* same for raw-backward */
} encoder_isr_t;

extern encoder_isr_t encoder_isr_state[ENCODER_MAX];
#endif /* !__ASSEMBLER__ */

#endif
