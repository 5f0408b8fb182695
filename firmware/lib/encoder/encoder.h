/*
 * Wheel encoder front end: up to ENCODER_MAX wheels, quadrature (x4) or
 * single-channel Hall pulse counting.
 *
 * Two halves:
 *   ISR side   encoder_isr_edge() is the hal_encoder_edge_fn hook. It only
 *              decodes, counts and timestamps into a small per-wheel record.
 *   loop side  encoder_snapshot() copies that record under hal_irq_save();
 *              encoder_update() (50 Hz task) turns counts into travel (um)
 *              and speed (mm/s) and keeps the health flags.
 *
 * Sign convention: a positive count / distance / speed is the wheel rolling
 * the robot forward (x forward, REP-103). Set cfg.invert on a wheel mounted
 * mirrored (e.g. the right wheel of a differential drive) so that this holds.
 *
 * Quadrature: ab = (A << 1) | B. A leading B (ab sequence 0,2,3,1,0) counts
 * up; B leading A (0,1,3,2,0) counts down. A jump in which both lines change
 * at once (0<->3, 1<->2) is illegal: it adds to `errors` and leaves the count
 * alone. Every level change adds one to `edges` (a repeated level is no edge).
 *
 * Hall mode: one count per pulse (with B low, the rising edge of A); the
 * sensor cannot tell direction, so each pulse is signed by the last non-zero
 * hint from encoder_set_direction_hint().
 *
 * Speed: two estimators, picked per wheel per update (see encoder_update()):
 *   period method   |counts this update| <  crossover_counts:
 *                   speed = travel_per_count * n / span, where span is the
 *                   time from the last stamped count seen by the previous
 *                   fold to the last one now, n the counts between (M/T
 *                   method; n = 1 at low speed, i.e. the single edge period).
 *                   It needs two stamped counts in one direction run, so the
 *                   first update after a start or a reversal uses the count
 *                   method. With no new edge the estimate decays as
 *                   travel_per_count / time_since_last_edge and is forced to
 *                   0 after stop_timeout_ms.
 *   count method    |counts this update| >= crossover_counts:
 *                   speed = counts * travel_per_count / update interval.
 * With crossover 8 the count method's quantisation is at most 1/8 at the
 * switch-over and shrinks as speed rises, while the period method is used
 * where the count method would be coarse (0..7 counts per tick).
 */
#ifndef AGNAV_ENCODER_H
#define AGNAV_ENCODER_H

#include <stdbool.h>
#include <stdint.h>

#include "params.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ENCODER_MAX 4u

/* Defaults used when a cfg field is 0. */
#define ENCODER_DEFAULT_CROSSOVER_COUNTS 8u
#define ENCODER_DEFAULT_STOP_TIMEOUT_MS 250u
/* Error-ratio health check: evaluated over windows of this many edges;
 * fault when errors * ENCODER_HEALTH_RATIO_DEN > edges (i.e. > 1/8 bad). */
#define ENCODER_HEALTH_WINDOW_EDGES 64u
#define ENCODER_HEALTH_RATIO_DEN 8u

typedef enum {
    ENCODER_MODE_QUAD_X4 = 0, /* A/B quadrature, all four edges counted */
    ENCODER_MODE_HALL = 1     /* one pulse line, direction from the hint */
} encoder_mode_t;

/* Per-wheel parameters. Travel per count is either given directly
 * (travel_per_count_nm != 0) or derived as pi * wheel_diameter_um /
 * counts_per_wheel_rev. Reference car of ref 003: Hall, 16 magnets on a
 * 69 mm wheel -> counts 16, diameter 69000 um (13.548 mm per pulse; the
 * thesis quotes 13.55 mm). */
typedef struct {
    uint8_t mode;                  /* encoder_mode_t */
    uint8_t invert;                /* nonzero: swap the counting direction */
    uint8_t crossover_counts;      /* speed method switch, counts per update; 0 = default 8 */
    uint16_t stop_timeout_ms;      /* no edge for this long -> speed 0; 0 = default 250 */
    uint32_t counts_per_wheel_rev; /* decoded counts per wheel turn (x4 and gearing folded in) */
    uint32_t wheel_diameter_um;    /* rolling diameter, micrometres */
    uint32_t travel_per_count_nm;  /* optional override: wheel travel per count, nanometres */
} encoder_cfg_t;

/* Totals up to now (the interrupt record folded in). count wraps modulo 2^32
 * (consumers use (int32_t)(new - old)); edges and errors wrap likewise.
 * The edge period is span_us / span_counts: the time between two stamped
 * counts of the current direction run and the counts between them (M/T
 * method, see encoder_update()); no division is done here. */
typedef struct {
    int32_t count;         /* signed counts, forward positive */
    uint32_t edges;        /* level changes since init: counted steps + illegal jumps */
    uint32_t errors;       /* illegal quadrature jumps since init */
    uint32_t last_edge_us; /* time of the last stamped count (4 us resolution) */
    uint32_t span_us;      /* period numerator; 0 with span_counts 0 = unknown */
    uint16_t span_counts;  /* period denominator, counts; 0 = unknown */
    int8_t dir;            /* sign of the last counted step: -1, 0 (none yet), +1 */
} encoder_snapshot_t;

/* Speed estimator used by the last update. */
typedef enum {
    ENCODER_SPEED_NONE = 0,   /* no information: 0 reported */
    ENCODER_SPEED_PERIOD = 1, /* travel per count / edge period */
    ENCODER_SPEED_DECAY = 2,  /* no edge this update: bounded by time since the last edge */
    ENCODER_SPEED_COUNT = 3,  /* count difference over the update interval */
    ENCODER_SPEED_STOPPED = 4 /* no edge for stop_timeout_ms */
} encoder_speed_method_t;

/* Health flags (encoder_motion_t.flags). */
#define ENCODER_F_ERROR_RATIO 0x01u /* last full window had > 1/8 illegal transitions */
#define ENCODER_F_STOPPED 0x02u     /* no edge for stop_timeout_ms (or never) */
#define ENCODER_F_UNCONFIGURED 0x80u

/* Loop-side result of the last encoder_update() for one wheel. */
typedef struct {
    int32_t delta_um;   /* travel since the previous update, micrometres, forward positive */
    int32_t speed_mm_s; /* signed wheel speed, mm/s */
    int32_t count;      /* count used by this update */
    uint32_t edges;     /* edge total used by this update (encoder_snapshot_t.edges then) */
    uint8_t method;     /* encoder_speed_method_t */
    uint8_t flags;      /* ENCODER_F_* */
} encoder_motion_t;

/* Fold a motor-side encoder into counts per wheel revolution:
 * lines_per_motor_rev * (4 in quadrature x4 mode, 1 in Hall mode)
 * * gear_num / gear_den, where gear_num/gear_den is motor turns per wheel
 * turn. Rounded to nearest; returns 0 if gear_den is 0. Init-time only. */
uint32_t encoder_counts_per_wheel_rev(uint16_t lines_per_motor_rev, uint8_t mode,
                                      uint16_t gear_num, uint16_t gear_den);

/* Configure `count` wheels (<= ENCODER_MAX) from cfg[0..count-1], clear all
 * counters, and attach encoder_isr_edge to the HAL. Returns false (and
 * leaves the offending wheel unconfigured) if a cfg gives no travel per
 * count. Also records hal_time_us() as the start of the first update interval. */
bool encoder_init(uint8_t count, const encoder_cfg_t *cfg);

/* The parameters (encoder_params.c, the robot's build): wheels with an encoder (1..4), their
 * encoder_mode_t, bit i of invert = wheel i counts the other way (mounted mirrored), and the travel
 * per count of every wheel. */
typedef struct {
    uint8_t count;
    uint8_t mode;
    uint8_t invert;
    int32_t nm_per_count;
} encoder_params_t;

extern encoder_params_t encoder_params;
extern const PARAMS_ROM param_group_t ENCODER_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

/* encoder_init() of p->count wheels, all of p->mode and p->nm_per_count. */
bool encoder_init_params(const encoder_params_t *p);

/* ISR hook (hal_encoder_edge_fn) of the sim and STM32 backends. ab = (A << 1) | B
 * after the edge, t_us the edge time. Counts and timestamps into the interrupt
 * record (encoder_isr.h), nothing else. The ATmega2560 board does not call it:
 * its PORTK vector is hand-written with the same rules (hal/avr/encoder_pcint_avr.S,
 * <= 60 cycles vector to reti, see BENCHMARKS.md). */
void encoder_isr_edge(uint8_t idx, uint8_t ab, uint32_t t_us);

/* Hall mode: direction for the following pulses, from the drive command.
 * sign > 0 forward, < 0 backward, 0 keeps the previous direction (a coasting
 * wheel keeps turning the way it did). Ignored in quadrature mode. */
void encoder_set_direction_hint(uint8_t idx, int8_t sign);

/* Atomic copy of wheel idx's ISR record. Returns false for a bad index. */
bool encoder_snapshot(uint8_t idx, encoder_snapshot_t *out);

/* Overwrite wheel idx's count (re-zeroing, tests). The loop-side reference
 * moves with it, so the next update reports no jump. */
void encoder_set_count(uint8_t idx, int32_t count);

/* 50 Hz task: for each configured wheel compute travel since the previous
 * call and speed, and update the health flags. now_us = hal_time_us();
 * wrap of both the 32-bit count and the 32-bit microsecond clock is
 * handled with signed differences (intervals must stay < 2^31 us). */
void encoder_update(uint32_t now_us);

/* Result of the last encoder_update() for wheel idx (zeros and
 * ENCODER_F_UNCONFIGURED for a bad or unconfigured index). */
void encoder_motion(uint8_t idx, encoder_motion_t *out);

/* Failsafe hook: bit i set when wheel i has ENCODER_F_ERROR_RATIO. */
uint8_t encoder_faults(void);

/* Travel per count in nanometres as configured (0 if unconfigured). */
uint32_t encoder_travel_per_count_nm(uint8_t idx);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_ENCODER_H */
