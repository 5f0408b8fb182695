/*
 * Wheel encoder front end. See encoder.h for the contract and the speed
 * estimator crossover.
 */
#include "encoder.h"

#include <stddef.h>

#include "encoder_isr.h"
#include "hal.h"

/* ---- quadrature decode --------------------------------------------------
 * Index (old << 2) | new with ab = (A << 1) | B. Forward (A leads B) walks
 * the Gray ring 0 -> 2 -> 3 -> 1 -> 0; backward walks it the other way.
 * Same state: 0 (repeated interrupt, no motion). Both lines changed: error.
 * The inverted table is the same with the signs swapped, so the ISR never
 * multiplies. Kept in RAM (32 bytes) because the ISR reads it. */
#define QERR ENCODER_QERR

static const int8_t QUAD_FWD[16] = {
    /* old 0 (00) -> new 0..3 */ 0, -1, +1, QERR,
    /* old 1 (01) */ +1, 0, QERR, -1,
    /* old 2 (10) */ -1, QERR, 0, +1,
    /* old 3 (11) */ QERR, +1, -1, 0,
};

static const int8_t QUAD_INV[16] = {
    0, +1, -1, QERR,
    -1, 0, QERR, +1,
    +1, QERR, 0, -1,
    QERR, -1, +1, 0,
};

/* Loop-side state and derived constants. */
typedef struct {
    uint32_t nm_per_count;     /* travel per count, nm; also (mm/s)*us for the period method */
    uint32_t um_q8_per_count;  /* travel per count, 1/256 um */
    int32_t max_fast_counts;   /* |counts| below which count * um_q8 fits int32 */
    uint32_t stop_timeout_us;
    uint8_t crossover_counts;
    uint8_t configured;
    uint8_t invert;
    uint8_t resid_q8;          /* carried sub-micrometre travel, 1/256 um, 0..255 */
    int32_t prev_count;
    uint32_t prev_edges;
    uint32_t prev_errors;
    /* 32-bit extension of the ISR's 16-bit counters (folded by fold()). */
    uint32_t ext_count, ext_edges, ext_errors;
    uint16_t seen_count, seen_edges, seen_errors;
    uint16_t win_edges;
    uint16_t win_errors;
    encoder_motion_t out;
} enc_loop_t;

/* Not volatile: the ISR is the only writer while interrupts are enabled, and
 * every other access sits between hal_irq_save()/hal_irq_restore(), which
 * are compiler barriers (external calls / asm with a memory clobber). This
 * lets the ISR keep values in registers instead of re-reading memory. */
encoder_isr_t encoder_isr_state[ENCODER_MAX];
#define s_isr encoder_isr_state
static enc_loop_t s_loop[ENCODER_MAX];
static uint32_t s_prev_update_us;

/* ---- ISR side --------------------------------------------------------- */

/* The generic hook (sim HAL, STM32): the same inline step the AVR ISR uses. */
void encoder_isr_edge(uint8_t idx, uint8_t ab, uint32_t t_us)
{
    if (idx >= ENCODER_MAX) {
        return;
    }
    encoder_isr_step(&s_isr[idx], (uint8_t)(ab & 3u), t_us);
}

/* Take the ISR's 16-bit counters into the 32-bit loop-side totals. Called with
 * interrupts masked. */
static void fold(uint8_t idx)
{
    enc_loop_t *w = &s_loop[idx];
    const encoder_isr_t *e = &s_isr[idx];
    w->ext_count += (uint32_t)(int32_t)(int16_t)(uint16_t)(e->count - w->seen_count);
    w->ext_edges += (uint16_t)(e->edges - w->seen_edges);
    w->ext_errors += (uint16_t)(e->errors - w->seen_errors);
    w->seen_count = e->count;
    w->seen_edges = e->edges;
    w->seen_errors = e->errors;
}

void encoder_set_direction_hint(uint8_t idx, int8_t sign)
{
    if (idx >= ENCODER_MAX || sign == 0) {
        return;
    }
    int8_t h = sign > 0 ? 1 : -1;
    if (s_loop[idx].invert != 0u) {
        h = (int8_t)-h;
    }
    s_isr[idx].hint = h; /* single byte: atomic store */
}

bool encoder_snapshot(uint8_t idx, encoder_snapshot_t *out)
{
    if (idx >= ENCODER_MAX || out == NULL) {
        return false;
    }
    encoder_isr_t *e = &s_isr[idx];
    hal_irq_state_t st = hal_irq_save();
    fold(idx);
    out->count = (int32_t)s_loop[idx].ext_count; /* two's complement view of the wrapping counter */
    out->edges = s_loop[idx].ext_edges;
    out->errors = s_loop[idx].ext_errors;
    out->last_edge_us = e->last_edge_us;
    out->period_us = e->last_edge_us - e->prev_edge_us; /* unsigned: right across the 2^32 wrap */
    out->dir = e->dir;
    hal_irq_restore(st);
    return true;
}

void encoder_set_count(uint8_t idx, int32_t count)
{
    if (idx >= ENCODER_MAX) {
        return;
    }
    hal_irq_state_t st = hal_irq_save();
    fold(idx);
    s_loop[idx].ext_count = (uint32_t)count;
    hal_irq_restore(st);
    s_loop[idx].prev_count = count;
}

/* ---- configuration ---------------------------------------------------- */

uint32_t encoder_counts_per_wheel_rev(uint16_t lines_per_motor_rev, uint8_t mode,
                                      uint16_t gear_num, uint16_t gear_den)
{
    if (gear_den == 0u) {
        return 0u;
    }
    uint64_t c = (uint64_t)lines_per_motor_rev * (mode == ENCODER_MODE_QUAD_X4 ? 4u : 1u);
    c *= gear_num;
    return (uint32_t)((c + gear_den / 2u) / gear_den);
}

static bool configure_wheel(uint8_t i, const encoder_cfg_t *cfg)
{
    enc_loop_t *w = &s_loop[i];
    uint32_t nm = cfg->travel_per_count_nm;
    if (nm == 0u && cfg->counts_per_wheel_rev != 0u) {
        /* pi * D / counts, with D in um -> nm: D * 1000 * pi / counts.
         * pi * 1e9 = 3141592654 (init time, 64-bit is fine here). */
        uint64_t num = (uint64_t)cfg->wheel_diameter_um * 3141592654ull;
        uint64_t den = (uint64_t)cfg->counts_per_wheel_rev * 1000000ull;
        uint64_t q = (num + den / 2u) / den;
        nm = q > 0xFFFFFFFFull ? 0u : (uint32_t)q;
    }
    w->invert = cfg->invert != 0u ? 1u : 0u;
    if (nm == 0u) {
        w->configured = 0u;
        return false;
    }
    w->nm_per_count = nm;
    w->um_q8_per_count = (uint32_t)(((uint64_t)nm * 256u + 500u) / 1000u);
    if (w->um_q8_per_count == 0u) {
        w->um_q8_per_count = 1u;
    }
    w->max_fast_counts = (int32_t)((uint32_t)(INT32_MAX - 255) / w->um_q8_per_count);
    w->stop_timeout_us = (uint32_t)(cfg->stop_timeout_ms != 0u ? cfg->stop_timeout_ms
                                                               : ENCODER_DEFAULT_STOP_TIMEOUT_MS) * 1000u;
    w->crossover_counts = cfg->crossover_counts != 0u ? cfg->crossover_counts
                                                      : (uint8_t)ENCODER_DEFAULT_CROSSOVER_COUNTS;
    w->configured = 1u;

    encoder_isr_t *e = &s_isr[i];
    if (cfg->mode == ENCODER_MODE_HALL) {
        e->table = NULL;
    } else {
        e->table = w->invert != 0u ? QUAD_INV : QUAD_FWD;
    }
    e->hint = w->invert != 0u ? -1 : 1;
    return true;
}

bool encoder_init(uint8_t count, const encoder_cfg_t *cfg)
{
    bool ok = true;
    if (count > ENCODER_MAX) {
        count = ENCODER_MAX;
        ok = false;
    }
    hal_irq_state_t st = hal_irq_save();
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        encoder_isr_t *e = &s_isr[i];
        e->count = 0u;
        e->edges = 0u;
        e->errors = 0u;
        e->last_edge_us = 0u;
        e->prev_edge_us = 0u;
        e->table = QUAD_FWD;
        e->ab = 0u;
        e->dir = 0;
        e->hint = 1;

        enc_loop_t *w = &s_loop[i];
        w->configured = 0u;
        w->invert = 0u;
        w->resid_q8 = 0u;
        w->prev_count = 0;
        w->prev_edges = 0u;
        w->prev_errors = 0u;
        w->ext_count = w->ext_edges = w->ext_errors = 0u;
        w->seen_count = w->seen_edges = w->seen_errors = 0u;
        w->win_edges = 0u;
        w->win_errors = 0u;
        w->out.delta_um = 0;
        w->out.speed_mm_s = 0;
        w->out.count = 0;
        w->out.method = ENCODER_SPEED_NONE;
        w->out.flags = ENCODER_F_UNCONFIGURED;
        if (i < count && cfg != NULL) {
            if (configure_wheel(i, &cfg[i])) {
                w->out.flags = ENCODER_F_STOPPED;
            } else {
                ok = false;
            }
        }
    }
    hal_irq_restore(st);
    s_prev_update_us = hal_time_us();
    hal_encoder_attach(count, encoder_isr_edge);
    return ok;
}

uint32_t encoder_travel_per_count_nm(uint8_t idx)
{
    return (idx < ENCODER_MAX && s_loop[idx].configured != 0u) ? s_loop[idx].nm_per_count : 0u;
}

/* ---- loop side -------------------------------------------------------- */

static int32_t iabs32(int32_t v) { return v < 0 ? -v : v; }

/* Travel for dc counts plus the carried fraction; returns whole um. */
static int32_t travel_um(enc_loop_t *w, int32_t dc)
{
    if (iabs32(dc) <= w->max_fast_counts) {
        int32_t acc = dc * (int32_t)w->um_q8_per_count + (int32_t)w->resid_q8;
        w->resid_q8 = (uint8_t)(acc & 0xFF);
        return acc >> 8; /* floor (arithmetic shift); the remainder stays in resid */
    }
    /* Rare: more than ~2 km of counts since the last update. */
    int64_t acc = (int64_t)dc * (int64_t)w->um_q8_per_count + (int64_t)w->resid_q8;
    w->resid_q8 = (uint8_t)(acc & 0xFF);
    acc >>= 8;
    if (acc > INT32_MAX) {
        acc = INT32_MAX;
    } else if (acc < INT32_MIN) {
        acc = INT32_MIN;
    }
    return (int32_t)acc;
}

/* |v| in mm/s for d_um of travel over the interval whose reciprocal is
 * recip_q16 = 65536000 / dt_us (worked out once per update). The product
 * fits 32 bits when both factors are below 2^16 (update interval >= 1 ms and
 * < 65 mm of travel); otherwise a 64-bit division (rare). */
static int32_t count_speed_mm_s(int32_t d_um, uint32_t recip_q16, int32_t dt_us)
{
    uint32_t mag = (uint32_t)iabs32(d_um);
    uint32_t v;
    if (mag <= 0xFFFFu && recip_q16 <= 0xFFFFu) {
        v = (mag * recip_q16 + 32768u) >> 16;
    } else {
        v = (uint32_t)(((uint64_t)mag * 1000u + (uint32_t)dt_us / 2u) / (uint32_t)dt_us);
    }
    if (v > (uint32_t)INT32_MAX) {
        v = (uint32_t)INT32_MAX;
    }
    return d_um < 0 ? -(int32_t)v : (int32_t)v;
}

void encoder_update(uint32_t now_us)
{
    int32_t dt_us = (int32_t)(now_us - s_prev_update_us);
    uint32_t recip_q16 = 0u;
    if (dt_us > 0) {
        /* Shared by all wheels: one division per update, not per wheel. */
        recip_q16 = (65536000u + (uint32_t)dt_us / 2u) / (uint32_t)dt_us;
        s_prev_update_us = now_us;
    }

    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        enc_loop_t *w = &s_loop[i];
        if (w->configured == 0u) {
            continue;
        }
        encoder_snapshot_t s;
        (void)encoder_snapshot(i, &s);

        int32_t dc = (int32_t)((uint32_t)s.count - (uint32_t)w->prev_count);
        w->prev_count = s.count;
        int32_t d_um = travel_um(w, dc);
        w->out.delta_um = d_um;
        w->out.count = s.count;

        /* ---- speed ---- */
        uint8_t flags = (uint8_t)(w->out.flags & ENCODER_F_ERROR_RATIO);
        int32_t adc = iabs32(dc);
        if (dt_us <= 0) {
            /* Same instant as the last update: keep the previous speed. */
        } else if (adc >= (int32_t)w->crossover_counts) {
            w->out.speed_mm_s = count_speed_mm_s(d_um, recip_q16, dt_us);
            w->out.method = ENCODER_SPEED_COUNT;
        } else if (s.dir == 0) {
            w->out.speed_mm_s = 0;
            w->out.method = ENCODER_SPEED_NONE;
            flags |= ENCODER_F_STOPPED;
        } else {
            int32_t since = (int32_t)(now_us - s.last_edge_us);
            if (since < 0) {
                since = 0;
            }
            if (dc == 0 && (uint32_t)since > w->stop_timeout_us) {
                w->out.speed_mm_s = 0;
                w->out.method = ENCODER_SPEED_STOPPED;
                flags |= ENCODER_F_STOPPED;
            } else if (s.period_us == 0u) {
                if (dc != 0) {
                    /* First count after a start or a reversal: no period yet. */
                    w->out.speed_mm_s = count_speed_mm_s(d_um, recip_q16, dt_us);
                    w->out.method = ENCODER_SPEED_COUNT;
                } else {
                    w->out.speed_mm_s = 0;
                    w->out.method = ENCODER_SPEED_NONE;
                }
            } else {
                /* Edge-period method. With no edge for longer than the last
                 * period the true speed is at most one count per `since`,
                 * so the estimate decays towards 0 until the stop timeout. */
                uint32_t p = s.period_us;
                uint8_t method = ENCODER_SPEED_PERIOD;
                if (dc == 0 && (uint32_t)since > p) {
                    p = (uint32_t)since;
                    method = ENCODER_SPEED_DECAY;
                }
                if (dc == 0 && method == ENCODER_SPEED_PERIOD && w->out.method == ENCODER_SPEED_PERIOD) {
                    /* Same edge pair as last time: same speed, skip the division. */
                } else {
                    int32_t v = (int32_t)((w->nm_per_count + p / 2u) / p); /* nm/us == mm/s */
                    w->out.speed_mm_s = s.dir < 0 ? -v : v;
                    w->out.method = method;
                }
            }
        }

        /* ---- health: illegal-transition ratio over windows of edges ---- */
        uint32_t de = s.edges - w->prev_edges;
        uint32_t dr = s.errors - w->prev_errors;
        w->prev_edges = s.edges;
        w->prev_errors = s.errors;
        if (de > 0xFFFFu) {
            de = 0xFFFFu;
        }
        if (dr > de) {
            dr = de;
        }
        uint32_t we = (uint32_t)w->win_edges + de;
        uint32_t wr = (uint32_t)w->win_errors + dr;
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
        w->out.flags = flags;
    }
}

void encoder_motion(uint8_t idx, encoder_motion_t *out)
{
    if (out == NULL) {
        return;
    }
    if (idx >= ENCODER_MAX || s_loop[idx].configured == 0u) {
        out->delta_um = 0;
        out->speed_mm_s = 0;
        out->count = 0;
        out->method = ENCODER_SPEED_NONE;
        out->flags = ENCODER_F_UNCONFIGURED;
        return;
    }
    *out = s_loop[idx].out;
}

uint8_t encoder_faults(void)
{
    uint8_t m = 0u;
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        if (s_loop[i].configured != 0u && (s_loop[i].out.flags & ENCODER_F_ERROR_RATIO) != 0u) {
            m = (uint8_t)(m | (1u << i));
        }
    }
    return m;
}
