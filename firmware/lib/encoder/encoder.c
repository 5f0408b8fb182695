/*
 * Wheel encoder front end. See encoder.h for the contract and the speed
 * estimator crossover, encoder_isr.h for the interrupt record.
 */
#include "encoder.h"

#include <stddef.h>

#include "encoder_isr.h"
#include "hal.h"
#include "units.h"

_Static_assert(sizeof(encoder_isr_t) == ENCODER_ISR_SIZE, "AVR vector layout");
_Static_assert(offsetof(encoder_isr_t, back) == ENCODER_ISR_OFS_BACK, "AVR vector layout");
_Static_assert(offsetof(encoder_isr_t, errors) == ENCODER_ISR_OFS_ERRORS, "AVR vector layout");
_Static_assert(offsetof(encoder_isr_t, fwd_stamp) == ENCODER_ISR_OFS_FWD_STAMP, "AVR vector layout");
_Static_assert(offsetof(encoder_isr_t, back_stamp) == ENCODER_ISR_OFS_BACK_STAMP, "AVR vector layout");

#define W_CONFIGURED 0x01u
#define W_INVERT 0x02u
#define W_HALL 0x04u
#define RUN_NO_REF 0xFFFFu /* run_n: no stamped step of the current run yet */

/* Loop-side state, per wheel. What fold() touches on every call comes first: the
 * AVR reaches struct fields through a pointer with a 0..63 byte displacement only. */
typedef struct {
    /* what was folded from the interrupt record */
    uint16_t seen_fwd, seen_back, seen_errors;
    uint8_t bits;                  /* W_* */
    int8_t hall_sign;              /* Hall: sign of a pulse in robot terms (hint, inverted) */
    int8_t dir;                    /* robot-terms sign of the last counted step, 0 = none yet */
    int8_t run_dir;                /* raw direction (+1 fwd, -1 back) of the current run, 0 = none */
    uint16_t run_n;                /* steps after ref_us (RUN_NO_REF: no reference yet) */
    uint16_t span_n;               /* period (M/T method): span_us over span_n steps, 0 = unknown */
    uint32_t span_us;
    uint32_t ref_us;               /* time of the last stamped step of the run */
    uint32_t last_edge_us;         /* time of the last stamped step */
    uint32_t count, edges, errors; /* 32-bit totals (count: two's complement view) */
    /* since the last encoder_update() */
    int32_t pend_count;
    uint16_t pend_edges, pend_errors;
    /* encoder_update() */
    uint16_t win_edges, win_errors;
    int32_t delta_um;
    int32_t speed_mm_s;
    uint8_t method;
    uint8_t flags;
    uint8_t resid_q8;              /* carried sub-micrometre travel, 1/256 um */
    uint8_t crossover_counts;
    /* configuration */
    uint16_t stop_timeout_ms;
    uint32_t nm_per_count;         /* travel per count, nm; also (mm/s)*us for the period method */
    uint32_t um_q8_per_count;      /* travel per count, 1/256 um */
} enc_loop_t;

/* Not volatile: the interrupt is the only writer while interrupts are enabled,
 * and the loop copies it between hal_irq_save()/hal_irq_restore(), which are
 * compiler barriers (external calls / asm with a memory clobber). */
encoder_isr_t encoder_isr_state[ENCODER_MAX];
#define s_isr encoder_isr_state
static enc_loop_t s_loop[ENCODER_MAX];
static uint32_t s_prev_update_us;
/* Generic hook only: last levels per encoder (the AVR vector keeps PINK in GPIOR1). */
static uint8_t s_levels[ENCODER_MAX];

/* ---- ISR side --------------------------------------------------------- */

void encoder_isr_edge(uint8_t idx, uint8_t ab, uint32_t t_us)
{
    if (idx >= ENCODER_MAX) {
        return;
    }
    ab &= 3u;
    uint8_t old = s_levels[idx];
    uint8_t changed = (uint8_t)(old ^ ab);
    s_levels[idx] = ab;
    if (changed == 0u) {
        return;
    }
    encoder_isr_t *e = &s_isr[idx];
    if (changed == 3u) {
        e->errors++;
        return;
    }
    uint16_t stamp = (uint16_t)(t_us >> ENCODER_STAMP_SHIFT);
    if (((ab >> 1) ^ old) & 1u) { /* A_new != B_old */
        if ((uint8_t)++e->fwd != 0u) {
            e->fwd_stamp = stamp;
        }
    } else {
        if ((uint8_t)++e->back != 0u) {
            e->back_stamp = stamp;
        }
    }
}

/* ---- folding the record into the loop-side totals --------------------- */

/* Microseconds of a stamp, given the time now (both in the same 2^18 us window);
 * 4 us resolution (the low bits of now are dropped). */
static uint32_t stamp_us(uint16_t stamp, uint32_t now_us)
{
    uint16_t age = (uint16_t)((uint16_t)(now_us >> ENCODER_STAMP_SHIFT) - stamp);
    return (now_us & ~(uint32_t)((1u << ENCODER_STAMP_SHIFT) - 1u)) - (uint32_t)age * (1u << ENCODER_STAMP_SHIFT);
}

static uint16_t sat_add16(uint16_t a, uint16_t b)
{
    uint16_t s = (uint16_t)(a + b);
    return s < a ? 0xFFFFu : s;
}

/* n steps of raw direction d, the last stamped one (stamped of the n) at t (if stamped > 0). */
static void run_steps(enc_loop_t *w, int8_t d, uint16_t n, uint16_t stamped, uint32_t t)
{
    if (d != w->run_dir) {
        /* start or reversal: no period until two stamped steps of this run */
        w->run_dir = d;
        w->run_n = RUN_NO_REF;
        w->span_n = 0u;
    }
    if (stamped == 0u) {
        if (w->run_n != RUN_NO_REF) {
            w->run_n = sat_add16(w->run_n, n);
            if (w->run_n == RUN_NO_REF) {
                w->run_n = RUN_NO_REF - 1u;
            }
        }
        return;
    }
    if (w->run_n != RUN_NO_REF) {
        uint32_t span_n = (uint32_t)w->run_n + stamped;
        w->span_us = t - w->ref_us;
        w->span_n = span_n > 0xFFFEu ? 0u : (uint16_t)span_n;
    }
    w->ref_us = t;
    w->run_n = (uint16_t)(n - stamped);
    w->last_edge_us = t;
}

/* Fold wheel w from a copy r of its interrupt record, taken at now_us. */
static void fold(enc_loop_t *w, const encoder_isr_t *r, uint32_t now_us)
{
    uint16_t df = (uint16_t)(r->fwd - w->seen_fwd);
    uint16_t db = (uint16_t)(r->back - w->seen_back);
    uint16_t de = (uint16_t)(r->errors - w->seen_errors);
    w->seen_fwd = r->fwd;
    w->seen_back = r->back;
    w->seen_errors = r->errors;
    uint16_t edges = (uint16_t)(df + db + de);
    w->edges += (uint32_t)df + db + de;
    w->errors += de;
    w->pend_edges = (uint16_t)(w->pend_edges + edges); /* the 50 Hz update empties them */
    w->pend_errors = (uint16_t)(w->pend_errors + de);

    /* stamped steps among the new ones (carry rule, encoder_isr.h) */
    uint16_t sf = (uint8_t)r->fwd == 0u ? (df > 0u ? (uint16_t)(df - 1u) : 0u) : df;
    uint16_t sb = (uint8_t)r->back == 0u ? (db > 0u ? (uint16_t)(db - 1u) : 0u) : db;
    int32_t dc;
    if ((w->bits & W_HALL) != 0u) {
        /* one raw-forward step per pulse, signed by the hint; db are the other edges */
        dc = w->hall_sign < 0 ? -(int32_t)df : (int32_t)df;
        if (df != 0u) {
            run_steps(w, w->hall_sign, df, sf, sf != 0u ? stamp_us(r->fwd_stamp, now_us) : 0u);
            w->dir = w->hall_sign;
        }
    } else {
        dc = (int32_t)df - (int32_t)db;
        if ((w->bits & W_INVERT) != 0u) {
            dc = -dc;
        }
        if (df != 0u && db != 0u) {
            /* reversal(s) within the interval: the later stamp tells the last direction */
            uint16_t now_st = (uint16_t)(now_us >> ENCODER_STAMP_SHIFT);
            bool fwd_last = (uint16_t)(now_st - r->fwd_stamp) <= (uint16_t)(now_st - r->back_stamp);
            w->run_dir = 0; /* the run restarts with the last step */
            if (fwd_last) {
                run_steps(w, 1, 1u, sf != 0u ? 1u : 0u, stamp_us(r->fwd_stamp, now_us));
            } else {
                run_steps(w, -1, 1u, sb != 0u ? 1u : 0u, stamp_us(r->back_stamp, now_us));
            }
        } else if (df != 0u) {
            run_steps(w, 1, df, sf, sf != 0u ? stamp_us(r->fwd_stamp, now_us) : 0u);
        } else if (db != 0u) {
            run_steps(w, -1, db, sb, sb != 0u ? stamp_us(r->back_stamp, now_us) : 0u);
        }
        if (w->run_dir != 0) {
            w->dir = (w->bits & W_INVERT) != 0u ? (int8_t)-w->run_dir : w->run_dir;
        }
    }
    w->count += (uint32_t)dc;
    w->pend_count += dc;
}

/* Copy wheel idx's record with interrupts masked (~30 cycles on the AVR). */
static void copy_record(uint8_t idx, encoder_isr_t *r)
{
    hal_irq_state_t st = hal_irq_save();
    *r = s_isr[idx];
    hal_irq_restore(st);
}

static bool record_changed(const enc_loop_t *w, const encoder_isr_t *r)
{
    return r->fwd != w->seen_fwd || r->back != w->seen_back || r->errors != w->seen_errors;
}

/* Copy the record, then read the clock (so every stamp in the copy is older), then
 * fold; no clock read when nothing happened since the last fold. */
static void fold_one(uint8_t idx)
{
    encoder_isr_t r;
    copy_record(idx, &r);
    if (record_changed(&s_loop[idx], &r)) {
        fold(&s_loop[idx], &r, hal_time_us());
    }
}

void encoder_set_direction_hint(uint8_t idx, int8_t sign)
{
    if (idx >= ENCODER_MAX || sign == 0) {
        return;
    }
    enc_loop_t *w = &s_loop[idx];
    if ((w->bits & W_HALL) == 0u) {
        return;
    }
    int8_t h = sign > 0 ? 1 : -1;
    if ((w->bits & W_INVERT) != 0u) {
        h = (int8_t)-h;
    }
    if (h != w->hall_sign) {
        fold_one(idx); /* pulses so far keep the old sign */
        w->hall_sign = h;
    }
}

bool encoder_snapshot(uint8_t idx, encoder_snapshot_t *out)
{
    if (idx >= ENCODER_MAX || out == NULL) {
        return false;
    }
    fold_one(idx);
    const enc_loop_t *w = &s_loop[idx];
    out->count = (int32_t)w->count;
    out->edges = w->edges;
    out->errors = w->errors;
    out->last_edge_us = w->last_edge_us;
    out->span_us = w->span_us;
    out->span_counts = w->span_n;
    out->dir = w->dir;
    return true;
}

void encoder_set_count(uint8_t idx, int32_t count)
{
    if (idx >= ENCODER_MAX) {
        return;
    }
    fold_one(idx);
    s_loop[idx].count = (uint32_t)count;
    s_loop[idx].pend_count = 0;
}

/* ---- configuration ---------------------------------------------------- */

/* (a * b + c / 2) / c in 64 bits (c > 0), truncated to 32 bits: the rare wide case of the speed
 * estimates, and configuration. Not inlined: its 64-bit multiply stays out of the control tick's code. */
__attribute__((noinline)) static uint32_t muldiv_round(uint32_t a, uint32_t b, uint32_t c)
{
    return (uint32_t)units_div_round_u64((uint64_t)a * b, c);
}

uint32_t encoder_counts_per_wheel_rev(uint16_t lines_per_motor_rev, uint8_t mode,
                                      uint16_t gear_num, uint16_t gear_den)
{
    if (gear_den == 0u) {
        return 0u;
    }
    uint64_t c = (uint64_t)lines_per_motor_rev * (mode == ENCODER_MODE_QUAD_X4 ? 4u : 1u);
    c *= gear_num;
    return (uint32_t)units_div_round_u64(c, gear_den);
}

/* pi * D / counts, with D in um -> nm: D * 1000 * pi / counts, rounded; 0 beyond 32 bits.
 * pi * 1e9 = 3141592654 (init time, 64-bit is fine here; not inlined, see muldiv_round). */
__attribute__((noinline)) static uint32_t travel_from_wheel_nm(uint32_t diameter_um, uint32_t counts)
{
    uint64_t q = units_div_round_u64((uint64_t)diameter_um * 3141592654ull, (uint64_t)counts * 1000000ull);
    return q > 0xFFFFFFFFull ? 0u : (uint32_t)q;
}

static bool configure_wheel(enc_loop_t *w, const encoder_cfg_t *cfg)
{
    uint32_t nm = cfg->travel_per_count_nm;
    if (nm == 0u && cfg->counts_per_wheel_rev != 0u) {
        nm = travel_from_wheel_nm(cfg->wheel_diameter_um, cfg->counts_per_wheel_rev);
    }
    w->bits = (uint8_t)((cfg->invert != 0u ? W_INVERT : 0u) | (cfg->mode == ENCODER_MODE_HALL ? W_HALL : 0u));
    w->hall_sign = cfg->invert != 0u ? -1 : 1;
    if (nm == 0u) {
        return false;
    }
    w->nm_per_count = nm;
    w->um_q8_per_count = muldiv_round(nm, 256u, 1000u);
    if (w->um_q8_per_count == 0u) {
        w->um_q8_per_count = 1u;
    }
    w->stop_timeout_ms = cfg->stop_timeout_ms != 0u ? cfg->stop_timeout_ms : (uint16_t)ENCODER_DEFAULT_STOP_TIMEOUT_MS;
    w->crossover_counts = cfg->crossover_counts != 0u ? cfg->crossover_counts
                                                      : (uint8_t)ENCODER_DEFAULT_CROSSOVER_COUNTS;
    w->bits |= W_CONFIGURED;
    return true;
}

bool encoder_init(uint8_t count, const encoder_cfg_t *cfg)
{
    bool ok = true;
    if (count > ENCODER_MAX) {
        count = ENCODER_MAX;
        ok = false;
    }
    uint8_t hall_mask = 0u;
    hal_irq_state_t st = hal_irq_save();
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        encoder_isr_t *e = &s_isr[i];
        e->fwd = e->back = e->errors = 0u;
        e->fwd_stamp = e->back_stamp = 0u;
        s_levels[i] = 0u;

        enc_loop_t *w = &s_loop[i];
        *w = (enc_loop_t){0};
        w->run_n = RUN_NO_REF;
        w->flags = ENCODER_F_UNCONFIGURED;
        if (i < count && cfg != NULL) {
            if (configure_wheel(w, &cfg[i])) {
                w->flags = ENCODER_F_STOPPED;
            } else {
                ok = false;
            }
            if (cfg[i].mode == ENCODER_MODE_HALL) {
                hall_mask = (uint8_t)(hall_mask | (1u << i));
            }
        }
    }
    hal_irq_restore(st);
    s_prev_update_us = hal_time_us();
    hal_encoder_attach(count, hall_mask, encoder_isr_edge);
    return ok;
}

uint32_t encoder_travel_per_count_nm(uint8_t idx)
{
    return (idx < ENCODER_MAX && (s_loop[idx].bits & W_CONFIGURED) != 0u) ? s_loop[idx].nm_per_count : 0u;
}

/* ---- loop side -------------------------------------------------------- */

/* travel_um() beyond 16 x 16 bit operands (|dc| >= 2^15 or >= 256 mm per count), in 32-bit
 * halves: x = dc * um_q8 + resid = hi * 2^32 + lo in two's complement, and x >> 8 (floor) =
 * hi * 2^24 + lo / 2^8, within int32 exactly when -128 <= hi <= 127, else clamped. Not inlined:
 * its 64-bit arithmetic stays out of the control tick's common path. */
__attribute__((noinline)) static int32_t travel_um_wide(enc_loop_t *w, int32_t dc)
{
    uint64_t p = (uint64_t)units_abs_u32(dc) * w->um_q8_per_count; /* unsigned 32 x 32 -> 64 */
    uint32_t lo = (uint32_t)p;
    uint32_t hi = (uint32_t)(p >> 32);
    if (dc < 0) {
        hi = ~hi + (lo == 0u ? 1u : 0u);
        lo = 0u - lo;
    }
    lo += w->resid_q8;
    if (lo < w->resid_q8) {
        hi++;
    }
    w->resid_q8 = (uint8_t)(lo & 0xFFu);
    if ((int32_t)hi > 127) {
        return INT32_MAX;
    }
    if ((int32_t)hi < -128) {
        return INT32_MIN;
    }
    return (int32_t)((hi << 24) | (lo >> 8));
}

/* Travel for dc counts plus the carried fraction; returns whole um. */
static int32_t travel_um(enc_loop_t *w, int32_t dc)
{
    /* |dc| < 2^15 and um_q8 < 2^16 (< 256 mm per count): the product fits int32 */
    if (units_abs_u32(dc) < 0x8000u && w->um_q8_per_count < 0x10000u) {
        /* 16 x 16 -> 32 bit operands: avr-gcc calls its short widening multiply */
        int32_t acc = (int32_t)(int16_t)dc * (int32_t)(uint16_t)w->um_q8_per_count + (int32_t)w->resid_q8;
        w->resid_q8 = (uint8_t)(acc & 0xFF);
        return acc >> 8; /* floor (arithmetic shift); the remainder stays in resid */
    }
    return travel_um_wide(w, dc);
}

/* |v| in mm/s for d_um of travel over the interval whose reciprocal is
 * recip_q16 = 65536000 / dt_us (worked out once per update). The product
 * fits 32 bits when both factors are below 2^16 (update interval >= 1 ms and
 * < 65 mm of travel); otherwise a 64-bit division (rare). */
static int32_t count_speed_mm_s(int32_t d_um, uint32_t recip_q16, int32_t dt_us)
{
    uint32_t mag = units_abs_u32(d_um);
    uint32_t v;
    if (mag <= 0xFFFFu && recip_q16 <= 0xFFFFu) {
        v = ((uint32_t)(uint16_t)mag * (uint16_t)recip_q16 + 32768u) >> 16; /* 16 x 16 -> 32 */
    } else {
        v = muldiv_round(mag, 1000u, (uint32_t)dt_us);
    }
    if (v > (uint32_t)INT32_MAX) {
        v = (uint32_t)INT32_MAX;
    }
    return d_um < 0 ? -(int32_t)v : (int32_t)v;
}

/* nm per count * n / span_us, rounded: nm/us == mm/s. One division. */
static int32_t period_speed_mm_s(uint32_t nm_per_count, uint16_t n, uint32_t span_us)
{
    if (span_us == 0u) {
        span_us = 1u;
    }
    if (nm_per_count < 0x1000000ul && n < 0x80u) { /* nm * n + span / 2 < 2^32 */
        return (int32_t)units_div_round_u32(nm_per_count * n, span_us);
    }
    return (int32_t)muldiv_round(nm_per_count, n, span_us);
}

/* a * n > c in 64 bits; not inlined (see muldiv_round) */
__attribute__((noinline)) static bool mul_exceeds(uint32_t a, uint16_t n, uint32_t c) { return (uint64_t)a * n > c; }

/* since > span_us / n, without a division */
static bool longer_than_period(uint32_t since_us, uint32_t span_us, uint16_t n)
{
    if (since_us < 0x10000ul) {
        return (uint32_t)(uint16_t)since_us * n > span_us; /* 16 x 16 -> 32 */
    }
    return mul_exceeds(since_us, n, span_us);
}

static void update_wheel(enc_loop_t *w, uint32_t now_us, int32_t dt_us, uint32_t recip_q16)
{
    int32_t dc = w->pend_count;
    w->pend_count = 0;
    int32_t d_um = travel_um(w, dc);
    w->delta_um = d_um;

    /* ---- speed ---- */
    uint8_t flags = (uint8_t)(w->flags & ENCODER_F_ERROR_RATIO);
    uint32_t adc = units_abs_u32(dc);
    if (dt_us <= 0) {
        /* Same instant as the last update: keep the previous speed. */
    } else if (adc >= (uint32_t)w->crossover_counts) {
        w->speed_mm_s = count_speed_mm_s(d_um, recip_q16, dt_us);
        w->method = ENCODER_SPEED_COUNT;
    } else if (w->dir == 0) {
        w->speed_mm_s = 0;
        w->method = ENCODER_SPEED_NONE;
        flags |= ENCODER_F_STOPPED;
    } else {
        int32_t since = (int32_t)(now_us - w->last_edge_us);
        if (since < 0) {
            since = 0;
        }
        if (dc == 0 && (uint32_t)since > (uint32_t)w->stop_timeout_ms * 1000u) {
            w->speed_mm_s = 0;
            w->method = ENCODER_SPEED_STOPPED;
            flags |= ENCODER_F_STOPPED;
        } else if (w->span_n == 0u) {
            if (dc != 0) {
                /* First counts after a start or a reversal: no period yet. */
                w->speed_mm_s = count_speed_mm_s(d_um, recip_q16, dt_us);
                w->method = ENCODER_SPEED_COUNT;
            } else {
                w->speed_mm_s = 0;
                w->method = ENCODER_SPEED_NONE;
            }
        } else if (dc == 0 && longer_than_period((uint32_t)since, w->span_us, w->span_n)) {
            /* No edge for longer than the last period: the true speed is at
             * most one count per `since`, so the estimate decays towards 0
             * until the stop timeout. */
            int32_t v = period_speed_mm_s(w->nm_per_count, 1u, (uint32_t)since);
            w->speed_mm_s = w->dir < 0 ? -v : v;
            w->method = ENCODER_SPEED_DECAY;
        } else if (dc == 0 && w->method == ENCODER_SPEED_PERIOD) {
            /* Same edges as last time: same speed, no division. */
        } else {
            /* Edge-period (M/T) method over the stamped steps of this run. */
            int32_t v = period_speed_mm_s(w->nm_per_count, w->span_n, w->span_us);
            w->speed_mm_s = w->dir < 0 ? -v : v;
            w->method = ENCODER_SPEED_PERIOD;
        }
    }

    /* ---- health: illegal-transition ratio over windows of edges ---- */
    uint32_t we = (uint32_t)w->win_edges + w->pend_edges;
    uint32_t wr = (uint32_t)w->win_errors + w->pend_errors;
    w->pend_edges = 0u;
    w->pend_errors = 0u;
    if (we >= ENCODER_HEALTH_WINDOW_EDGES) {
        if (wr * ENCODER_HEALTH_RATIO_DEN > we) {
            flags |= ENCODER_F_ERROR_RATIO;
        } else {
            flags = (uint8_t)(flags & ~ENCODER_F_ERROR_RATIO);
        }
        we = 0u;
        wr = 0u;
    }
    w->win_edges = (uint16_t)we;
    w->win_errors = (uint16_t)wr;
    w->flags = flags;
}

void encoder_update(uint32_t now_us)
{
    hal_encoder_poll(); /* hardware-counted wheels into their records (STM32 timers) */
    /* Records first, one short masked copy each, then the clock: every stamp is older. */
    encoder_isr_t r[ENCODER_MAX];
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        copy_record(i, &r[i]);
    }
    uint32_t copy_us = hal_time_us();

    int32_t dt_us = (int32_t)(now_us - s_prev_update_us);
    uint32_t recip_q16 = 0u;
    if (dt_us > 0) {
        /* Shared by all wheels: one division per update, not per wheel. */
        recip_q16 = units_div_round_u32(65536000u, (uint32_t)dt_us);
        s_prev_update_us = now_us;
    }
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        enc_loop_t *w = &s_loop[i];
        if ((w->bits & W_CONFIGURED) == 0u) {
            continue;
        }
        if (record_changed(w, &r[i])) {
            fold(w, &r[i], copy_us);
        }
        update_wheel(w, now_us, dt_us, recip_q16);
    }
}

void encoder_motion(uint8_t idx, encoder_motion_t *out)
{
    if (out == NULL) {
        return;
    }
    if (idx >= ENCODER_MAX || (s_loop[idx].bits & W_CONFIGURED) == 0u) {
        out->delta_um = 0;
        out->speed_mm_s = 0;
        out->count = 0;
        out->edges = 0u;
        out->method = ENCODER_SPEED_NONE;
        out->flags = ENCODER_F_UNCONFIGURED;
        return;
    }
    const enc_loop_t *w = &s_loop[idx];
    out->delta_um = w->delta_um;
    out->speed_mm_s = w->speed_mm_s;
    out->count = (int32_t)(w->count - (uint32_t)w->pend_count); /* the count of the last update */
    out->edges = w->edges - w->pend_edges;                          /* likewise */
    out->method = w->method;
    out->flags = w->flags;
}

uint8_t encoder_faults(void)
{
    uint8_t m = 0u;
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        if ((s_loop[i].bits & W_CONFIGURED) != 0u && (s_loop[i].flags & ENCODER_F_ERROR_RATIO) != 0u) {
            m = (uint8_t)(m | (1u << i));
        }
    }
    return m;
}
