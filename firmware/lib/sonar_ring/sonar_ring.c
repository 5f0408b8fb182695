/* Sonar ring: grouped firing, echo classification, median filter, frames.
 * See sonar_ring.h for the schedule and the conversion. */
#include "sonar_ring.h"

#include "hal.h"

/* ---- compile-time half of the cross-talk proof ------------------------- */
/* Stride grouping (group = i % G) keeps neighbours i, i+1 apart for G >= 2,
 * and the wrap pair (n-1, 0) apart when n % G != 1 (init fixes the rest). */
_Static_assert(SONAR_GROUPS >= 2u, "neighbours need different groups");
_Static_assert(SONAR_RING_MAX % SONAR_GROUPS == 0u, "full ring: wrap pair 11/0 must fall in different groups");
/* Different groups fire >= one slot apart, so the slot is the neighbour gap. */
_Static_assert(SONAR_SLOT_US >= SONAR_NEIGHBOUR_GAP_US, "slot shorter than the cross-talk gap");
/* A full ring pass within 100 ms: >= 10 Hz. */
_Static_assert(SONAR_RING_PERIOD_US <= 100000UL, "full ring slower than 10 Hz");
/* The slowest echo (rise window + max-range timeout) must end inside the slot. */
_Static_assert(SONAR_RISE_TIMEOUT_US < SONAR_SLOT_US, "rise window longer than slot");
/* A working sensor's longest pulse (HC-SR04 with nothing in range: 38 ms) ends before the fall
 * deadline even when it starts at the end of the rise window. */
_Static_assert(SONAR_FALL_TIMEOUT_US > SONAR_RISE_TIMEOUT_US + 38000UL, "fall deadline cuts free-space pulses");
/* The last group's verdicts are in before the next pass's first group must be classified
 * (one slot after it fired), so a late frame never delays a firing of a ring of >= 2 groups. */
_Static_assert(SONAR_FALL_TIMEOUT_US < 2u * SONAR_SLOT_US, "fall deadline beyond the next group's slot");

/* ---- presets ------------------------------------------------------------ */
/* ref 002: 12 sensors, 30 deg apart, S0 front, S6 back; radius 225 mm (the
 * SDLG-1 is 0.45 m across). x = 225 cos(b), y = 225 sin(b). */
static const UNITS_ROM sonar_cfg_t RING12[12] = {
    {0, 225, 0, 4000u},          {3000, 195, 113, 4000u},   {6000, 113, 195, 4000u},
    {9000, 0, 225, 4000u},       {12000, -113, 195, 4000u}, {15000, -195, 113, 4000u},
    {18000, -225, 0, 4000u},     {-15000, -195, -113, 4000u}, {-12000, -113, -195, 4000u},
    {-9000, 0, -225, 4000u},     {-6000, 113, -195, 4000u}, {-3000, 195, -113, 4000u},
};
const sonar_ring_cfg_t SONAR_RING_12_SDLG = {RING12, 12u};

/* ref 001: six HC-SR04, two per side, one front, one back (ordered CCW). */
static const UNITS_ROM sonar_cfg_t RING6[6] = {
    {0, 250, 0, 4000u},      {9000, 150, 200, 4000u},   {9000, -150, 200, 4000u},
    {18000, -250, 0, 4000u}, {-9000, -150, -200, 4000u}, {-9000, 150, -200, 4000u},
};
const sonar_ring_cfg_t SONAR_RING_6_HCSR04 = {RING6, 6u};

static const UNITS_ROM sonar_cfg_t RING1[1] = {{0, 200, 0, 4000u}};
const sonar_ring_cfg_t SONAR_RING_1_SRF05 = {RING1, 1u};

/* ---- ISR side ------------------------------------------------------------ */
#define ECHO_ROSE 0x01u
#define ECHO_FELL 0x02u
/* Set by the loop side at the firing, verdict at classification (the ISR keeps them): */
#define ECHO_STUCK 0x04u /* line already high at the trigger: FAULT */
#define ECHO_SKIP 0x08u  /* not fired (cross-talk guard): STALE */

typedef struct {
    uint32_t rise_us;
    uint32_t fall_us;
    uint8_t flags; /* ECHO_ROSE / ECHO_FELL since the last trigger, ECHO_STUCK / ECHO_SKIP */
    uint8_t level; /* last edge seen: 1 high, 0 low */
} echo_isr_t;

static volatile echo_isr_t s_isr[SONAR_RING_MAX];
static volatile uint8_t s_isr_count;

void sonar_ring_isr_echo(uint8_t idx, uint8_t level, uint32_t t_us)
{
    if (idx >= s_isr_count) {
        return;
    }
    volatile echo_isr_t *e = &s_isr[idx];
    if (level != 0u) {
        if ((e->flags & ECHO_ROSE) == 0u) {
            e->rise_us = t_us;
            e->flags = (uint8_t)(e->flags | ECHO_ROSE);
        }
        e->level = 1u;
    } else {
        if ((e->flags & (ECHO_ROSE | ECHO_FELL)) == ECHO_ROSE) {
            e->fall_us = t_us;
            e->flags = (uint8_t)(e->flags | ECHO_FELL);
        }
        e->level = 0u;
    }
}

/* ---- loop side ------------------------------------------------------------ */
typedef struct {
    const UNITS_ROM sonar_cfg_t *cfg;
    uint8_t n;
    uint8_t n_groups;
    uint8_t group_of[SONAR_RING_MAX];
    uint16_t timeout_us[SONAR_RING_MAX]; /* echo width at max range */
    uint16_t max_mm[SONAR_RING_MAX];     /* clamped max range */

    uint8_t cur_group;
    bool measuring;
    bool fired_once;
    uint32_t group_fire_us;              /* when cur_group fired */
    uint16_t pending;                    /* bit i: sensor i awaits classification */
    uint16_t await_fall;                 /* bit i: echo still high at its max-range timeout */
    bool publish_due;                    /* pass classified, frame waits for await_fall */
    uint16_t fired_mask;                 /* bit i: last_fire_us[i] valid */
    uint32_t last_fire_us[SONAR_RING_MAX];

    uint16_t hist_mm[SONAR_RING_MAX][3]; /* last valid readings, for the median */
    uint8_t hist_n[SONAR_RING_MAX];
    uint8_t hist_pos[SONAR_RING_MAX];

    uint16_t work_mm[SONAR_RING_MAX];    /* pass being built */
    uint8_t work_status[SONAR_RING_MAX];

    sonar_frame_t frame;                 /* last complete pass */
    bool fresh;
    uint16_t faults[SONAR_RING_MAX];
    uint16_t guard_skips;
} ring_t;

static ring_t s;

uint16_t sonar_ring_mm_from_echo_us(uint32_t echo_us)
{
    /* 343 m/s, round trip: mm = us * 343 / 2000 = us * 0.1715. Done as a
     * multiply and shift, 0.1715 ~ 11239 / 65536 (0.17149, -0.003 %), which
     * avoids a 32-bit division (~700 cycles on the AVR). The product fits
     * 32 bits up to 382000 us; longer pulses saturate. */
    if (echo_us > 382000UL) {
        return 65535u;
    }
    uint32_t mm = (echo_us * 11239UL + 32768UL) >> 16;
    return mm > 65535UL ? 65535u : (uint16_t)mm;
}

uint32_t sonar_ring_echo_us_from_mm(uint16_t range_mm)
{
    return ((uint32_t)range_mm * 2000UL + 342UL) / 343UL;
}

static uint16_t median3(const uint16_t *h, uint8_t n)
{
    if (n == 1u) {
        return h[0];
    }
    if (n == 2u) {
        /* Two readings: the nearer one (conservative for obstacle checks). */
        return h[0] < h[1] ? h[0] : h[1];
    }
    uint16_t a = h[0], b = h[1], c = h[2];
    if (a > b) {
        uint16_t t = a;
        a = b;
        b = t;
    }
    /* now a <= b */
    if (c <= a) {
        return a;
    }
    return c < b ? c : b;
}

static void finish(uint8_t i, uint8_t status, uint16_t raw_mm)
{
    s.pending = (uint16_t)(s.pending & ~(1u << i));
    s.work_status[i] = status;
    switch (status) {
    case SONAR_VALID:
        s.hist_mm[i][s.hist_pos[i]] = raw_mm;
        s.hist_pos[i] = (uint8_t)((s.hist_pos[i] + 1u) % 3u);
        if (s.hist_n[i] < 3u) {
            s.hist_n[i]++;
        }
        s.work_mm[i] = median3(s.hist_mm[i], s.hist_n[i]);
        break;
    case SONAR_NO_ECHO:
        s.work_mm[i] = s.max_mm[i];
        break;
    case SONAR_FAULT:
        if (s.faults[i] < 65535u) {
            s.faults[i]++;
        }
        s.work_mm[i] = 0u;
        break;
    default:
        s.work_mm[i] = 0u;
        break;
    }
}

/* Decide sensor i of the measuring group, if its echo is complete. */
static void classify(uint8_t i, uint32_t now_us, bool force)
{
    uint32_t rise_us, fall_us;
    uint8_t flags;
    hal_irq_state_t irq = hal_irq_save();
    flags = s_isr[i].flags;
    rise_us = s_isr[i].rise_us;
    fall_us = s_isr[i].fall_us;
    hal_irq_restore(irq);

    if ((flags & ECHO_SKIP) != 0u) {
        finish(i, SONAR_STALE, 0u);
        return;
    }
    if ((flags & ECHO_STUCK) != 0u) {
        finish(i, SONAR_FAULT, 0u); /* a new ping cannot start on a line that is high */
        return;
    }
    uint32_t since_fire = now_us - s.group_fire_us;
    if ((flags & ECHO_ROSE) == 0u) {
        if (force || since_fire >= SONAR_RISE_TIMEOUT_US) {
            finish(i, SONAR_FAULT, 0u); /* missing sensor or dead echo line */
        }
        return;
    }
    if ((uint32_t)(rise_us - s.group_fire_us) > SONAR_RISE_TIMEOUT_US) {
        finish(i, SONAR_FAULT, 0u); /* rise far too late: not our ping */
        return;
    }
    if ((flags & ECHO_FELL) != 0u) {
        uint32_t width = fall_us - rise_us;
        if (width >= s.timeout_us[i]) {
            finish(i, SONAR_NO_ECHO, 0u);
        } else {
            finish(i, SONAR_VALID, sonar_ring_mm_from_echo_us(width));
        }
        return;
    }
    if (force || (uint32_t)(now_us - rise_us) >= s.timeout_us[i]) {
        /* Still high at max range: free space if the pulse ends (settle_fall decides), a line
         * stuck high if it does not. The group goes on without it. */
        s.pending = (uint16_t)(s.pending & ~(1u << i));
        s.await_fall = (uint16_t)(s.await_fall | (1u << i));
    }
}

/* Verdicts on echoes that were still high at their max-range timeout: NO_ECHO once the line
 * falls within SONAR_FALL_TIMEOUT_US of the trigger, FAULT when it has not by then. */
static void settle_fall(uint32_t now_us)
{
    for (uint8_t i = 0; i < s.n; i++) {
        if ((s.await_fall & (1u << i)) == 0u) {
            continue;
        }
        hal_irq_state_t irq = hal_irq_save();
        uint8_t flags = s_isr[i].flags;
        uint32_t fall_us = s_isr[i].fall_us;
        hal_irq_restore(irq);
        uint32_t fire_us = s.last_fire_us[i];
        if ((flags & ECHO_FELL) != 0u) {
            bool in_time = (uint32_t)(fall_us - fire_us) < SONAR_FALL_TIMEOUT_US;
            finish(i, in_time ? SONAR_NO_ECHO : SONAR_FAULT, 0u);
        } else if ((uint32_t)(now_us - fire_us) >= SONAR_FALL_TIMEOUT_US) {
            finish(i, SONAR_FAULT, 0u); /* echo line stuck high */
        } else {
            continue;
        }
        s.await_fall = (uint16_t)(s.await_fall & ~(1u << i));
    }
}

static bool neighbour_fired_recently(uint8_t i, uint32_t now_us)
{
    if (s.n < 2u) {
        return false;
    }
    uint8_t left = (uint8_t)((i + 1u) % s.n);
    uint8_t right = (uint8_t)((i + s.n - 1u) % s.n);
    if ((s.fired_mask & (1u << left)) != 0u && (uint32_t)(now_us - s.last_fire_us[left]) < SONAR_NEIGHBOUR_GAP_US) {
        return true;
    }
    if ((s.fired_mask & (1u << right)) != 0u && (uint32_t)(now_us - s.last_fire_us[right]) < SONAR_NEIGHBOUR_GAP_US) {
        return true;
    }
    return false;
}

/* Fires group g, unless one of its sensors still awaits the end of its previous echo (only a
 * 1-group ring fires a sensor again within SONAR_FALL_TIMEOUT_US): then the next step tries again.
 * Verdicts known at the firing (skipped, line already high) are left to classify(), so a frame
 * still waiting for the previous pass's last group gets none of this pass's readings. */
static void fire_group(uint8_t g, uint32_t now_us)
{
    for (uint8_t i = 0; i < s.n; i++) {
        if (s.group_of[i] == g && (s.await_fall & (1u << i)) != 0u) {
            return;
        }
    }
    s.group_fire_us = now_us;
    s.pending = 0u;
    for (uint8_t i = 0; i < s.n; i++) {
        if (s.group_of[i] != g) {
            continue;
        }
        s.pending = (uint16_t)(s.pending | (1u << i));
        bool skip = neighbour_fired_recently(i, now_us);
        hal_irq_state_t irq = hal_irq_save();
        uint8_t stuck_high = s_isr[i].level;
        s_isr[i].flags = skip ? ECHO_SKIP : stuck_high != 0u ? ECHO_STUCK : 0u;
        hal_irq_restore(irq);
        if (skip) {
            if (s.guard_skips < 65535u) {
                s.guard_skips++;
            }
            continue;
        }
        s.last_fire_us[i] = now_us;
        s.fired_mask = (uint16_t)(s.fired_mask | (1u << i));
        if (stuck_high == 0u) {
            hal_sonar_trigger(i);
        }
    }
    s.measuring = true;
    s.fired_once = true;
}

static void publish(uint32_t now_us)
{
    for (uint8_t i = 0; i < s.n; i++) {
        s.frame.ranges_mm[i] = s.work_mm[i];
        s.frame.status[i] = s.work_status[i];
    }
    s.frame.stamp_us = now_us;
    s.frame.seq++;
    s.fresh = true;
}

bool sonar_ring_init(const sonar_ring_cfg_t *cfg)
{
    uint8_t *p = (uint8_t *)&s;
    for (uint16_t k = 0; k < sizeof s; k++) {
        p[k] = 0u;
    }
    s_isr_count = 0u;
    for (uint8_t i = 0; i < SONAR_RING_MAX; i++) {
        s_isr[i].flags = 0u;
        s_isr[i].level = 0u;
        s.work_status[i] = SONAR_STALE;
        s.frame.status[i] = SONAR_STALE;
    }
    if (cfg == 0 || cfg->sensor == 0 || cfg->count == 0u || cfg->count > SONAR_RING_MAX) {
        return false;
    }
    s.cfg = cfg->sensor;
    s.n = cfg->count;
    s.frame.count = s.n;
    s.n_groups = s.n < SONAR_GROUPS ? s.n : (uint8_t)SONAR_GROUPS;
    for (uint8_t i = 0; i < s.n; i++) {
        s.group_of[i] = (uint8_t)(i % s.n_groups);
    }
    if (s.n > 2u && s.group_of[s.n - 1u] == s.group_of[0]) {
        /* n % 3 == 1: sensor n-2 is in group 2, sensor 0 in group 0. */
        s.group_of[s.n - 1u] = 1u;
    }
    const uint32_t max_echo_us = SONAR_SLOT_US - SONAR_RISE_TIMEOUT_US;
    for (uint8_t i = 0; i < s.n; i++) {
        uint32_t t = sonar_ring_echo_us_from_mm(s.cfg[i].max_range_mm);
        if (t > max_echo_us) {
            t = max_echo_us;
        }
        s.timeout_us[i] = (uint16_t)t;
        s.max_mm[i] = sonar_ring_mm_from_echo_us(t);
        if (s.max_mm[i] > s.cfg[i].max_range_mm) {
            s.max_mm[i] = s.cfg[i].max_range_mm;
        }
    }
    s_isr_count = s.n;
    hal_sonar_attach(s.n, sonar_ring_isr_echo);
    return true;
}

void sonar_ring_step(uint32_t now_us)
{
    if (s.n == 0u) {
        return;
    }
    hal_sonar_poll(); /* echo edges the HAL queued (avr) reach sonar_ring_isr_echo now */
    if (s.await_fall != 0u) {
        settle_fall(now_us);
    }
    /* While a frame waits (publish_due), the group fired since keeps its echo stamps and is
     * classified once the frame is out. */
    if (s.measuring && !s.publish_due) {
        bool force = (uint32_t)(now_us - s.group_fire_us) >= SONAR_SLOT_US;
        for (uint8_t i = 0; i < s.n; i++) {
            if ((s.pending & (1u << i)) != 0u) {
                classify(i, now_us, force);
            }
        }
        if (s.pending == 0u) {
            s.measuring = false;
            s.cur_group++;
            if (s.cur_group >= s.n_groups) {
                s.cur_group = 0u;
                s.publish_due = true;
            }
        }
    }
    /* A pass's frame goes out once its echoes still high at max range have ended (await_fall);
     * the next group fires on time regardless. */
    if (s.publish_due && s.await_fall == 0u) {
        s.publish_due = false;
        publish(now_us);
    }
    if (s.measuring) {
        return;
    }
    /* Next group: at least one slot after the previous group's real firing. */
    if (!s.fired_once || (uint32_t)(now_us - s.group_fire_us) >= SONAR_SLOT_US) {
        fire_group(s.cur_group, now_us);
    }
}

bool sonar_ring_snapshot(sonar_frame_t *out)
{
    bool was_fresh = s.fresh;
    if (out != 0) {
        *out = s.frame;
    }
    s.fresh = false;
    return was_fresh;
}

uint32_t sonar_ring_frames_completed(void) { return s.frame.seq; }

uint16_t sonar_ring_fault_count(uint8_t idx) { return idx < SONAR_RING_MAX ? s.faults[idx] : 0u; }

uint16_t sonar_ring_guard_skips(void) { return s.guard_skips; }

uint8_t sonar_ring_group_of(uint8_t idx) { return idx < s.n ? s.group_of[idx] : 0xFFu; }

bool sonar_ring_schedule_ok(void)
{
    if (s.n < 2u) {
        return s.n == 1u;
    }
    for (uint8_t i = 0; i < s.n; i++) {
        uint8_t j = (uint8_t)((i + 1u) % s.n);
        if (s.group_of[i] == s.group_of[j]) {
            return false;
        }
    }
    return true;
}
