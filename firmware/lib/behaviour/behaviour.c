/* Behaviour layers (failsafe, avoid obstacle, manual, follow wall, host
 * command, move to goal) and their subsumption arbiter. See behaviour.h. */
#include "behaviour.h"

#include "units.h"

/* ---- integer trigonometry --------------------------------------------- */
/* cos(5 deg * k) in Q14, k = 0..18 */
static const UNITS_ROM int16_t COS5_Q14[19] = {16384, 16322, 16135, 15826, 15396, 14849, 14189, 13421, 12551, 11585,
                                     10531, 9397,  8192,  6924,  5604,  4240,  2845,  1428,  0};
/* atan(k / 16) in cdeg, k = 0..16 */
static const UNITS_ROM int16_t ATAN16_CDEG[17] = {0,    358,  713,  1062, 1404, 1735, 2056, 2363, 2657,
                                        2936, 3201, 3451, 3687, 3909, 4119, 4315, 4500};

int32_t behaviour_wrap_cdeg(int32_t a)
{
    /* Subtraction instead of a 32-bit modulo (hundreds of cycles on AVR);
     * inputs are sums of a few angles, so this loops at most a few times. */
    if (a >= 360000L || a <= -360000L) {
        a %= 36000L;
    }
    while (a >= 18000L) {
        a -= 36000L;
    }
    while (a < -18000L) {
        a += 36000L;
    }
    return a;
}

int16_t behaviour_cos_q14(int32_t angle_cdeg)
{
    int32_t a = behaviour_wrap_cdeg(angle_cdeg);
    if (a < 0) {
        a = -a; /* cos is even: a in 0..18000 */
    }
    int16_t sign = 1;
    if (a > 9000L) {
        a = 18000L - a;
        sign = -1;
    }
    uint8_t k = (uint8_t)(a / 500L);
    int32_t frac = a % 500L;
    int32_t v = COS5_Q14[k];
    if (k < 18u) {
        v += ((int32_t)(COS5_Q14[k + 1u] - COS5_Q14[k]) * frac) / 500L;
    }
    return (int16_t)(sign * v);
}

int16_t behaviour_sin_q14(int32_t angle_cdeg) { return behaviour_cos_q14(angle_cdeg - 9000L); }

int16_t behaviour_atan2_cdeg(int32_t y, int32_t x)
{
    if (x == 0 && y == 0) {
        return 0;
    }
    uint32_t ax = units_abs_u32(x);
    uint32_t ay = units_abs_u32(y);
    while ((ax | ay) > 0x7FFFFUL) { /* keep the Q12 ratio inside 32 bits */
        ax >>= 1;
        ay >>= 1;
    }
    bool steep = ay > ax;
    uint32_t num = steep ? ax : ay;
    uint32_t den = steep ? ay : ax;
    uint32_t q = (num * 4096UL) / den; /* tan in Q12, 0..4096 */
    uint8_t k = (uint8_t)(q >> 8);
    int32_t frac = (int32_t)(q & 0xFFu);
    int32_t ang = ATAN16_CDEG[k];
    if (k < 16u) {
        ang += ((int32_t)(ATAN16_CDEG[k + 1u] - ATAN16_CDEG[k]) * frac) / 256L;
    }
    if (steep) {
        ang = 9000L - ang;
    }
    if (x < 0) {
        ang = 18000L - ang;
    }
    if (y < 0) {
        ang = -ang;
    }
    return (int16_t)ang;
}

static uint32_t isqrt32(uint32_t v)
{
    uint32_t res = 0u;
    uint32_t bit = 1UL << 30;
    while (bit > v) {
        bit >>= 2;
    }
    while (bit != 0u) {
        if (v >= res + bit) {
            v -= res + bit;
            res = (res >> 1) + bit;
        } else {
            res >>= 1;
        }
        bit >>= 2;
    }
    return res;
}

static uint32_t hypot_mm(int32_t dx, int32_t dy)
{
    uint32_t ax = units_abs_u32(dx);
    uint32_t ay = units_abs_u32(dy);
    uint8_t shift = 0u;
    while ((ax | ay) > 32767UL) {
        ax >>= 1;
        ay >>= 1;
        shift++;
    }
    return isqrt32(ax * ax + ay * ay) << shift;
}

static int16_t clamp16(int32_t v, int16_t lim)
{
    if (v > lim) {
        return lim;
    }
    if (v < -(int32_t)lim) {
        return (int16_t)-lim;
    }
    return (int16_t)v;
}

/* ---- state ----------------------------------------------------------------- */
/* Sensor classes, from the mounting bearing (see behaviour_init). */
#define CLS_AXIS 0x01u       /* |b| < 15 deg: "dead ahead" (front extent, canyon test) */
#define CLS_LEFT 0x02u       /* 15 <= b < 90 deg: left extent l */
#define CLS_RIGHT 0x04u      /* -90 < b <= -15 deg: right extent r */
#define CLS_CONE 0x08u       /* |b| <= avoid_cone: passive-safety front cone */
#define CLS_REAR 0x10u       /* |b| >= 180 - avoid_cone: back-off check */
#define CLS_FRONT_SIDE 0x20u /* 15 <= |b| <= 45 deg: S1/S11, follow-wall exit test */

typedef enum { AV_CLEAR = 0, AV_STOP, AV_BACKOFF, AV_WAIT } avoid_state_t;

typedef struct {
    int16_t steer_cdeg;
    int16_t speed_mm_s;
    uint8_t reason;
} proposal_t;

static struct {
    behaviour_params_t p;
    const sonar_ring_cfg_t *ring;
    uint8_t n;
    uint16_t cos_milli[SONAR_RING_MAX]; /* cos(bearing) * 1000, only where > 0 */
    uint8_t cls[SONAR_RING_MAX];
    uint32_t imin;                      /* 1/km */
    uint32_t imax;
    uint16_t engage_mm;                 /* Imin horizon as a range */
    uint32_t wall_speed_q16;            /* wall_speed * 65536 / (Imax - Imin) */

    bool estop_latched;
    bool wd_latched;
    bool wd_prev_input;
    bool have_prev;
    uint32_t prev_ms;

    uint8_t av_state;
    uint32_t av_t_ms;
    uint32_t av_backoff_um;

    bool timer_on[2];                   /* canyon timers: [0] left, [1] right */
    uint32_t timer_end_ms[2];
    uint32_t wall_l, wall_r;
    /* follow-wall sums of frame pre_seq, from behaviour_sonar_frame() (valid when pre_valid) */
    bool pre_valid;
    bool pre_side_clear;
    uint8_t pre_near; /* CLS_LEFT / CLS_RIGHT: a side sensor there closer than avoid_stop */
    uint32_t pre_seq;
    uint32_t pre_l, pre_r, pre_f;
    uint32_t goal_dist_mm;              /* this tick, when goal seek is on and a goal is set */
    int32_t goal_err_cdeg;              /* goal bearing minus heading, -18000..17999 */
    bool goal_on;                       /* this tick: goal seek enabled, a goal set and not held */

    /* failsafe hold (behaviour.h) */
    uint8_t held;                       /* HOLD_* layers waiting for a fresh command */
    bool new_session;                   /* boot or arm since the host layer was last released */
    bool was_stop;                      /* the last tick was a stop failsafe */
    uint8_t held_gen[4];                /* host, manual, goal, mode counts when the last stop began */
    uint16_t held_seq;                  /* host setpoint sequence number then */
} b;

#define HOLD_HOST 1u
#define HOLD_MANUAL 2u
#define HOLD_GOAL 4u
#define HOLD_WALL 8u
#define HOLD_ALL 15u

#define SIDE_LEFT 0u
#define SIDE_RIGHT 1u

void behaviour_init(const behaviour_params_t *params, const sonar_ring_cfg_t *ring)
{
    uint8_t *z = (uint8_t *)&b;
    for (uint16_t k = 0; k < sizeof b; k++) {
        z[k] = 0u;
    }
    b.ring = ring;
    b.held = HOLD_ALL; /* a boot waits for a first command like the end of a failsafe */
    b.new_session = true;
    b.n = (ring != 0 && ring->sensor != 0) ? ring->count : 0u;
    if (b.n > SONAR_RING_MAX) {
        b.n = SONAR_RING_MAX;
    }
    behaviour_set_params(params);
}

void behaviour_set_params(const behaviour_params_t *params)
{
    b.p = *params;
    const sonar_ring_cfg_t *ring = b.ring;
    for (uint8_t i = 0; i < b.n; i++) {
        int16_t br = (int16_t)behaviour_wrap_cdeg(ring->sensor[i].bearing_cdeg);
        int16_t c = behaviour_cos_q14(br);
        b.cos_milli[i] = c > 0 ? (uint16_t)(((int32_t)c * 1000L + 8192L) >> 14) : 0u;
        int16_t ab = (int16_t)units_abs_u32(br);
        uint8_t cls = 0u;
        if (ab < 1500) {
            cls |= CLS_AXIS;
        } else if (ab < 9000) {
            cls |= br > 0 ? CLS_LEFT : CLS_RIGHT;
        }
        if (ab >= 1500 && ab <= 4500) {
            cls |= CLS_FRONT_SIDE;
        }
        if (ab <= b.p.avoid_cone_cdeg) {
            cls |= CLS_CONE;
        }
        if (ab >= 18000 - b.p.avoid_cone_cdeg) {
            cls |= CLS_REAR;
        }
        b.cls[i] = cls;
    }
    /* Imin / Imax (ref 002; the formulas are lost in the text, reconstructed):
     * the paper keeps the robot at least one step vmax*dt from any obstacle
     * and ties both thresholds to that step. Here each is the extent that a
     * single head-on obstacle (cos = 1) produces at a horizon of N steps:
     *   Imax = 1 / (N_max * vmax * dt + R0)   closer -> stop translating
     *   Imin = 1 / (N_min * vmax * dt + R0)   farther -> layer does not act */
    uint32_t step_mm = ((uint32_t)(b.p.wall_speed_mm_s > 0 ? b.p.wall_speed_mm_s : 0) * b.p.wall_dt_ms) / 1000UL;
    uint32_t hmax = (uint32_t)b.p.wall_imax_steps * step_mm;
    uint32_t hmin = (uint32_t)b.p.wall_imin_steps * step_mm;
    b.imax = 1000000UL / (hmax + b.p.wall_r0_mm + 1UL);
    b.imin = 1000000UL / (hmin + b.p.wall_r0_mm + 1UL);
    if (b.imin >= b.imax) {
        b.imin = b.imax > 1u ? b.imax - 1u : 0u;
    }
    b.engage_mm = hmin > 65535UL ? 65535u : (uint16_t)hmin;
    uint32_t vw = b.p.wall_speed_mm_s > 0 ? (uint32_t)b.p.wall_speed_mm_s : 0u;
    b.wall_speed_q16 = (b.imax > b.imin) ? (vw << 16) / (b.imax - b.imin) : 0u;
}

void behaviour_arm(void)
{
    b.estop_latched = false;
    b.wd_latched = false;
    b.held &= (uint8_t)~HOLD_WALL;
    b.new_session = true;
}

void behaviour_wall_extents(uint32_t *l_per_km, uint32_t *r_per_km)
{
    if (l_per_km != 0) {
        *l_per_km = b.wall_l;
    }
    if (r_per_km != 0) {
        *r_per_km = b.wall_r;
    }
}

static bool fresh(bool valid, uint32_t rx_ms, uint32_t now_ms, uint16_t timeout_ms)
{
    return valid && (uint32_t)(now_ms - rx_ms) <= timeout_ms;
}

static uint8_t frame_n(const sonar_frame_t *fr)
{
    if (fr->seq == 0u) {
        return 0u; /* no complete ring yet */
    }
    return fr->count < b.n ? fr->count : b.n;
}

static uint8_t sonar_n(const behaviour_in_t *in) { return frame_n(&in->sonar); }

/* ---- layer: failsafe ------------------------------------------------------- */
static uint8_t failsafe_flags(const behaviour_in_t *in)
{
    if (in->estop) {
        b.estop_latched = true;
    }
    if (in->reset_was_watchdog && !b.wd_prev_input) {
        b.wd_latched = true;
    }
    b.wd_prev_input = in->reset_was_watchdog;

    uint8_t f = 0u;
    if (b.estop_latched) {
        f |= BHV_FS_ESTOP;
    }
    bool link = fresh(in->heartbeat_valid, in->heartbeat_rx_ms, in->now_ms, b.p.link_timeout_ms) ||
                fresh(in->host_valid, in->host_rx_ms, in->now_ms, b.p.link_timeout_ms) ||
                fresh(in->manual_valid, in->manual_rx_ms, in->now_ms, b.p.link_timeout_ms);
    if (!link) {
        f |= BHV_FS_LINK_LOSS;
    }
    if (in->encoder_fault) {
        f |= BHV_FS_ENCODER_FAULT;
    }
    if (in->sonar_fault) {
        f |= BHV_FS_SONAR_FAULT;
    }
    if (b.wd_latched) {
        f |= BHV_FS_WATCHDOG_RESET;
    }
    if (in->calib_defaulted) {
        f |= BHV_FS_CALIB_DEFAULTED;
    }
    return f;
}

/* The failsafe hold (behaviour.h): a stop holds all command layers, and its first tick notes the
 * count of each kind of command taken so far; once the stop is over a layer is released by a command
 * of its kind taken since (the host layer's also newer than the last setpoint before the stop, unless
 * a new session began: a boot or an arm). */
static void update_holds(const behaviour_in_t *in, bool stop)
{
    bool start = stop && !b.was_stop;
    b.was_stop = stop;
    if (start) {
        b.held_gen[0] = in->host_gen;
        b.held_gen[1] = in->manual_gen;
        b.held_gen[2] = in->goal_gen;
        b.held_gen[3] = in->mode_gen;
        b.held_seq = in->host_seq;
    }
    if (stop) {
        b.held = HOLD_ALL;
        return;
    }
    uint8_t h = b.held;
    if ((h & HOLD_HOST) != 0u && in->host_gen != b.held_gen[0] &&
        (b.new_session || (int16_t)(in->host_seq - b.held_seq) > 0)) {
        h &= (uint8_t)~(HOLD_HOST | HOLD_WALL);
    }
    if ((h & HOLD_MANUAL) != 0u && in->manual_gen != b.held_gen[1]) {
        h &= (uint8_t)~(HOLD_MANUAL | HOLD_WALL);
    }
    if ((h & HOLD_GOAL) != 0u && in->goal_gen != b.held_gen[2]) {
        h &= (uint8_t)~(HOLD_GOAL | HOLD_WALL);
    }
    if (in->mode_gen != b.held_gen[3]) {
        h &= (uint8_t)~HOLD_WALL;
    }
    if ((h & HOLD_HOST) == 0u) {
        b.new_session = false; /* an arm while the host layer runs starts nothing: a replay stays a replay */
    }
    b.held = h;
}

static uint8_t failsafe_reason(uint8_t f)
{
    if ((f & BHV_FS_ESTOP) != 0u) {
        return BHV_REASON_ESTOP;
    }
    if ((f & BHV_FS_WATCHDOG_RESET) != 0u) {
        return BHV_REASON_WATCHDOG_BOOT;
    }
    if ((f & (BHV_FS_ENCODER_FAULT | BHV_FS_SONAR_FAULT)) != 0u) {
        return BHV_REASON_SENSOR_FAULT;
    }
    return BHV_REASON_LINK_LOSS;
}

/* ---- layer: move to goal --------------------------------------------------- */
static bool layer_goal(proposal_t *pr)
{
    if (!b.goal_on) {
        return false;
    }
    uint32_t dist = b.goal_dist_mm;
    if (dist <= b.p.goal_tol_mm) {
        pr->steer_cdeg = 0;
        pr->speed_mm_s = 0;
        pr->reason = BHV_REASON_GOAL_REACHED;
        return true;
    }
    int32_t err = b.goal_err_cdeg;
    int32_t speed = b.p.goal_speed_mm_s;
    if (dist < b.p.goal_slow_mm) {
        speed = (int32_t)(((uint32_t)b.p.goal_speed_mm_s * dist) / b.p.goal_slow_mm);
    }
    if (err > 6000L || err < -6000L) {
        speed = b.p.goal_min_speed_mm_s; /* goal well off the nose: crawl while turning */
    }
    if (speed < b.p.goal_min_speed_mm_s) {
        speed = b.p.goal_min_speed_mm_s;
    }
    pr->steer_cdeg = clamp16(err, b.p.max_steer_cdeg); /* steer straight at the goal bearing */
    pr->speed_mm_s = (int16_t)speed;
    pr->reason = BHV_REASON_GOAL_SEEK;
    return true;
}

/* ---- layer: host command --------------------------------------------------- */
static bool layer_host(const behaviour_in_t *in, proposal_t *pr)
{
    if ((b.held & HOLD_HOST) != 0u || !fresh(in->host_valid, in->host_rx_ms, in->now_ms, b.p.host_timeout_ms)) {
        return false;
    }
    pr->steer_cdeg = in->host_steer_cdeg;
    pr->speed_mm_s = in->host_speed_mm_s;
    pr->reason = BHV_REASON_HOST_SETPOINT;
    return true;
}

/* ---- layer: follow wall (ref 002) --------------------------------------- */
static bool timer_running(uint8_t side, uint32_t now_ms)
{
    return b.timer_on[side] && (int32_t)(b.timer_end_ms[side] - now_ms) > 0;
}

static void timer_start(uint8_t side, uint32_t now_ms)
{
    b.timer_on[side] = true;
    b.timer_end_ms[side] = now_ms + b.p.wall_canyon_ms;
}

/* cos_milli * 1000 / (R + R0) in 1/km, with one 16-bit division instead
 * of a 32-bit one (AVR: ~200 instead of ~700 cycles):
 *   recip = 64000 / ((R + R0) / 4) = 256000 / (R + R0)   (rounded)
 *   term  = cos_milli * recip / 256
 * Error: < 1 % for R + R0 >= 400 mm, < 3 % down to R0. */
static uint32_t extent_term(uint16_t cos_milli, uint16_t range_mm)
{
    uint32_t d = (uint32_t)range_mm + b.p.wall_r0_mm;
    if (d > 65535UL) {
        d = 65535UL;
    }
    uint16_t q = (uint16_t)(d >> 2);
    if (q == 0u) {
        q = 1u;
    }
    uint16_t recip = (uint16_t)(64000u / q);
    uint16_t rem = (uint16_t)(64000u % q); /* same division call */
    if (rem >= (uint16_t)(q - rem)) {
        recip++; /* round to nearest */
    }
    return ((uint32_t)cos_milli * recip) >> 8;
}

/* The follow-wall sums of the first n sensors of a frame into b.pre_* (see layer_wall). */
static void wall_sums(const sonar_frame_t *fr, uint8_t n)
{
    /* Obstacle extents (ref 002, the equation is lost in the text;
     * reconstructed from its description):
     *   l = sum over left sensors  of cos(a_i) / (R_i + R0)
     *   r = sum over right sensors of cos(a_i) / (R_i + R0)
     * a_i: sensor bearing; cos(a_i) weights obstacles ahead most and drops
     * sensors at 90 deg and behind; R0 keeps the terms finite; a sensor with
     * no echo counts with its detection range (NO_ECHO carries max range).
     * Integer form: term = cos_milli * 1000 / (R_mm + R0_mm), unit 1/km.
     * The dead-ahead sensors (|a| < 15 deg) form a separate front extent f. */
    uint32_t l = 0u, r = 0u, f = 0u;
    bool side_clear = true;
    uint8_t near = 0u;
    for (uint8_t i = 0; i < n; i++) {
        uint8_t st = fr->status[i];
        if (st != SONAR_VALID && st != SONAR_NO_ECHO) {
            continue; /* no information (faults are the failsafe's job) */
        }
        uint16_t rng = fr->ranges_mm[i];
        if ((b.cls[i] & CLS_FRONT_SIDE) != 0u && st == SONAR_VALID && rng < b.engage_mm) {
            side_clear = false;
        }
        if (st == SONAR_VALID && rng < b.p.avoid_stop_mm) {
            near |= (uint8_t)(b.cls[i] & (CLS_LEFT | CLS_RIGHT));
        }
        if ((b.cls[i] & (CLS_AXIS | CLS_LEFT | CLS_RIGHT)) == 0u || b.cos_milli[i] == 0u) {
            continue;
        }
        uint32_t term = extent_term(b.cos_milli[i], rng);
        if ((b.cls[i] & CLS_LEFT) != 0u) {
            l += term;
        } else if ((b.cls[i] & CLS_RIGHT) != 0u) {
            r += term;
        } else {
            f += term;
        }
    }
    b.pre_l = l;
    b.pre_r = r;
    b.pre_f = f;
    b.pre_side_clear = side_clear;
    b.pre_near = near;
    b.pre_seq = fr->seq;
}

void behaviour_sonar_frame(const sonar_frame_t *frame)
{
    wall_sums(frame, frame_n(frame));
    b.pre_valid = true;
}

static bool layer_wall(const behaviour_in_t *in, proposal_t *pr)
{
    uint8_t n = sonar_n(in);
    b.wall_l = 0u;
    b.wall_r = 0u;
    if ((in->mode_flags & BHV_MODE_FOLLOW_WALL) == 0u || n == 0u || (b.held & HOLD_WALL) != 0u) {
        return false;
    }
    if (!b.pre_valid || b.pre_seq != in->sonar.seq) {
        b.pre_valid = false; /* computed here for this frame only */
        wall_sums(&in->sonar, n);
    }
    uint32_t l = b.pre_l, r = b.pre_r, f = b.pre_f;
    bool side_clear = b.pre_side_clear;
    b.wall_l = l;
    b.wall_r = r;
    bool blocked = f >= b.imin; /* something dead ahead inside the engage horizon */
    if (l < b.imin && r < b.imin && !blocked) {
        return false; /* nothing near: lower layers run unrestrained */
    }
    /* Exit condition (ref 002 eq. 8): goal in the front half and nothing on
     * the front-side sensors (S1, S11) -> leave the wall to move-to-goal.
     * Not while a side sensor on the goal's side is closer than avoid_stop:
     * move-to-goal would turn into what stands there (a post 3 cm off at
     * 60 deg, beside the front-side sensors, was swept in the simulator). */
    if (b.goal_on && side_clear && !blocked) {
        int32_t zeta = b.goal_err_cdeg; /* angle robot heading -> goal */
        uint8_t toward = zeta > 0 ? CLS_LEFT : zeta < 0 ? CLS_RIGHT : 0u;
        if (zeta >= -9000L && zeta <= 9000L && (b.pre_near & toward) == 0u) {
            return false;
        }
    }

    /* Translation: full layer speed beyond the Imin horizon, zero at Imax. */
    uint32_t e = l > r ? l : r;
    if (f > e) {
        e = f;
    }
    int32_t speed;
    if (e >= b.imax) {
        speed = 0;
    } else if (e <= b.imin) {
        speed = b.p.wall_speed_mm_s;
    } else {
        speed = (int32_t)((b.wall_speed_q16 * (b.imax - e)) >> 16);
    }

    int32_t diff = (int32_t)l - (int32_t)r; /* > 0: left nearer -> turn right */
    uint8_t reason = l >= r ? BHV_REASON_WALL_LEFT : BHV_REASON_WALL_RIGHT;
    int32_t steer;
    bool timers = b.p.wall_canyon_ms != 0u;
    if (blocked) {
        /* Dead ahead is blocked: pick a side and turn at the fixed turn steer
         * (the paper's discrete rotate choice). In a canyon this choice flips
         * every time the turn brings the other wall closer: the canyon effect. */
        int8_t dir; /* +1 left, -1 right */
        if (diff > (int32_t)b.p.wall_deadband) {
            dir = -1;
        } else if (diff < -(int32_t)b.p.wall_deadband) {
            dir = 1;
        } else {
            dir = b.p.wall_tie_dir >= 0 ? 1 : -1;
        }
        /* Canyon timers (ref 002 fig. 9, lost; reconstructed): Start-timer(X, T)
         * when turning toward X; while Test-timer(X) is true a turn toward
         * the other side is refused and the robot keeps turning toward X.
         * The timer is restarted every tick the front stays blocked, so the
         * robot keeps one turn direction for the whole dead end and for T
         * after it clears instead of swaying left-right. */
        if (timers) {
            uint8_t want = dir > 0 ? SIDE_LEFT : SIDE_RIGHT;
            uint8_t other = (uint8_t)(1u - want);
            if (timer_running(other, in->now_ms)) {
                dir = (int8_t)-dir;
                want = other;
                reason = BHV_REASON_CANYON_TIMER;
            }
            timer_start(want, in->now_ms);
        }
        steer = (int32_t)dir * b.p.wall_turn_steer_cdeg;
    } else {
        /* Front open: proportional steering away from the nearer side, i.e.
         * along the wall, with a deadband for a balanced corridor. */
        if (diff <= (int32_t)b.p.wall_deadband && diff >= -(int32_t)b.p.wall_deadband) {
            steer = 0;
        } else {
            steer = -(diff * (int32_t)b.p.wall_gain_q4) / 16L;
            steer = clamp16(steer, b.p.wall_turn_steer_cdeg);
        }
        /* A correction against a running canyon timer is refused (no turn). */
        if (timers && steer != 0) {
            uint8_t other = steer > 0 ? SIDE_RIGHT : SIDE_LEFT;
            if (timer_running(other, in->now_ms)) {
                steer = 0;
                reason = BHV_REASON_CANYON_TIMER;
            }
        }
    }
    pr->steer_cdeg = (int16_t)steer;
    pr->speed_mm_s = (int16_t)speed;
    pr->reason = reason;
    return true;
}

/* ---- layer: manual ------------------------------------------------------- */
static bool layer_manual(const behaviour_in_t *in, proposal_t *pr)
{
    if ((b.held & HOLD_MANUAL) != 0u || !fresh(in->manual_valid, in->manual_rx_ms, in->now_ms, b.p.manual_timeout_ms)) {
        return false;
    }
    pr->steer_cdeg = in->manual_steer_cdeg;
    pr->speed_mm_s = in->manual_speed_mm_s;
    pr->reason = BHV_REASON_MANUAL_OVERRIDE;
    return true;
}

/* ---- layer: avoid obstacle (passive motion safety, ref 001) ------------- */
/* An obstacle in the front cone while moving forward: stop, step back a few
 * centimetres, wait for the obstacle (a person, most likely) to move, then
 * hand control back. If the path is still blocked the cycle repeats, which
 * also lets a turning robot creep around a wall it faces (ref 001 §3.4). */
static bool layer_avoid(const behaviour_in_t *in, bool lower_has, const proposal_t *lower, uint16_t dt_ms,
                        proposal_t *pr)
{
    if ((in->mode_flags & BHV_MODE_AVOID) == 0u || b.held == HOLD_ALL) {
        b.av_state = AV_CLEAR; /* off, or nothing commanded since a failsafe: no back-off either */
        return false;
    }
    uint8_t n = sonar_n(in);
    bool front = false, rear = false;
    for (uint8_t i = 0; i < n; i++) {
        if (in->sonar.status[i] != SONAR_VALID) {
            continue;
        }
        if ((b.cls[i] & CLS_CONE) != 0u && in->sonar.ranges_mm[i] < b.p.avoid_stop_mm) {
            front = true;
        }
        if ((b.cls[i] & CLS_REAR) != 0u && in->sonar.ranges_mm[i] < b.p.avoid_rear_clear_mm) {
            rear = true;
        }
    }
    bool forward = (lower_has && lower->speed_mm_s > 0) || in->speed_mm_s > b.p.avoid_moving_mm_s;
    int16_t v = (int16_t)units_abs_u32(in->speed_mm_s);
    uint32_t in_state_ms = in->now_ms - b.av_t_ms;

    if (b.av_state == AV_WAIT && in_state_ms >= b.p.avoid_wait_ms) {
        b.av_state = AV_CLEAR; /* release */
    }
    if (b.av_state == AV_CLEAR) {
        if (!(front && forward)) {
            return false;
        }
        b.av_state = AV_STOP;
        b.av_t_ms = in->now_ms;
        in_state_ms = 0u;
    }
    if (b.av_state == AV_STOP && in_state_ms >= b.p.avoid_stop_ms && v <= b.p.avoid_moving_mm_s) {
        b.av_state = AV_BACKOFF;
        b.av_t_ms = in->now_ms;
        b.av_backoff_um = 0u;
        in_state_ms = 0u;
    }
    if (b.av_state == AV_BACKOFF) {
        /* distance from odometry: integrate the measured speed */
        b.av_backoff_um += (uint32_t)v * dt_ms;
        uint32_t spd = b.p.avoid_backoff_speed_mm_s > 0 ? (uint32_t)b.p.avoid_backoff_speed_mm_s : 1u;
        uint32_t cap_ms = 2UL * ((uint32_t)b.p.avoid_backoff_mm * 1000UL / spd) + 200UL;
        if (b.av_backoff_um >= (uint32_t)b.p.avoid_backoff_mm * 1000UL || rear || in_state_ms >= cap_ms) {
            b.av_state = AV_WAIT;
            b.av_t_ms = in->now_ms;
        }
    }
    pr->steer_cdeg = 0;
    switch (b.av_state) {
    case AV_STOP:
        pr->speed_mm_s = 0;
        pr->reason = BHV_REASON_OBSTACLE_STOP;
        break;
    case AV_BACKOFF:
        pr->speed_mm_s = (int16_t)-b.p.avoid_backoff_speed_mm_s;
        pr->reason = BHV_REASON_OBSTACLE_BACKOFF;
        break;
    default:
        pr->speed_mm_s = 0;
        pr->reason = BHV_REASON_OBSTACLE_WAIT;
        break;
    }
    return true;
}

/* ---- arbiter ------------------------------------------------------------- */
void behaviour_step(const behaviour_in_t *in, behaviour_out_t *out)
{
    uint16_t dt_ms = 20u;
    if (b.have_prev) {
        uint32_t d = in->now_ms - b.prev_ms;
        dt_ms = d > 1000UL ? 1000u : (uint16_t)d;
    }
    b.have_prev = true;
    b.prev_ms = in->now_ms;

    uint8_t flags = failsafe_flags(in);
    out->failsafe_flags = flags;
    update_holds(in, (flags & BHV_FS_STOP_MASK) != 0u);

    b.goal_on = (in->mode_flags & BHV_MODE_GOAL_SEEK) != 0u && in->goal_active && (b.held & HOLD_GOAL) == 0u;
    if (b.goal_on) {
        /* once per tick, shared by move-to-goal and the follow-wall exit test */
        int32_t dx = in->goal_x_mm - in->x_mm;
        int32_t dy = in->goal_y_mm - in->y_mm;
        b.goal_dist_mm = hypot_mm(dx, dy);
        b.goal_err_cdeg = behaviour_wrap_cdeg((int32_t)behaviour_atan2_cdeg(dy, dx) - in->heading_cdeg);
    }

    /* Lower layers first, lowest priority first: a higher one overwrites. */
    proposal_t best = {0, 0, BHV_REASON_NO_COMMAND};
    proposal_t pr;
    uint8_t layer = BHV_LAYER_IDLE;
    if (layer_goal(&pr)) {
        best = pr;
        layer = BHV_LAYER_MOVE_TO_GOAL;
    }
    if (layer_host(in, &pr)) {
        best = pr;
        layer = BHV_LAYER_HOST_COMMAND;
    }
    if (layer_wall(in, &pr)) {
        best = pr;
        layer = BHV_LAYER_FOLLOW_WALL;
    }
    if (layer_manual(in, &pr)) {
        best = pr;
        layer = BHV_LAYER_MANUAL;
    }

    if ((flags & BHV_FS_STOP_MASK) != 0u) {
        /* Failsafe: immediate zero speed (no ramp). A ramp at a deceleration
         * limit would keep executing a command that is already stale for up
         * to link_timeout_ms; the drive stage's own slew limit is the only
         * smoothing. The passive-safety sequence restarts from scratch. */
        b.av_state = AV_CLEAR;
        out->steer_cdeg = 0;
        out->speed_mm_s = 0;
        out->layer = BHV_LAYER_FAILSAFE;
        out->reason = failsafe_reason(flags);
        return;
    }
    if (layer_avoid(in, layer != BHV_LAYER_IDLE, &best, dt_ms, &pr)) {
        best = pr;
        layer = BHV_LAYER_AVOID_OBSTACLE;
    }
    out->steer_cdeg = clamp16(best.steer_cdeg, b.p.max_steer_cdeg);
    out->speed_mm_s = clamp16(best.speed_mm_s, b.p.max_speed_mm_s);
    out->layer = layer;
    out->reason = best.reason;
}
