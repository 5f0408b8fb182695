/*
 * Integer dead reckoning. See odometry.h for the model, frames and error
 * budget. Pure logic: no HAL calls.
 */
#include "odometry.h"

#include <stddef.h>

#include "behaviour.h"
#include "units.h"

/* sin(i * 90deg / 64) in Q15 (32768 = 1.0), i = 0..64. Linear interpolation
 * between entries: max error (pi/128)^2 / 8 = 7.5e-5, plus 1.5e-5 rounding. */
static const UNITS_ROM uint16_t SIN_Q15[65] = {
    0, 804, 1608, 2411, 3212, 4011, 4808, 5602, 6393, 7180, 7962, 8740, 9512,
    10279, 11039, 11793, 12540, 13279, 14010, 14733, 15447, 16151, 16846, 17531,
    18205, 18868, 19520, 20160, 20788, 21403, 22006, 22595, 23170, 23732, 24279,
    24812, 25330, 25833, 26320, 26791, 27246, 27684, 28106, 28511, 28899, 29269,
    29622, 29957, 30274, 30572, 30853, 31114, 31357, 31581, 31786, 31972, 32138,
    32286, 32413, 32522, 32610, 32679, 32729, 32758, 32768,
};

/* tan(i * 0.5 degrees) in Q24 (16777216 = 1.0), i = 0..90. Curvature needs
 * relative accuracy at small angles, hence 24 bits. Linear interpolation
 * overestimates by at most h^2/8 * tan'' with h = 0.5 deg: relative 2e-5
 * below 20 deg, 3.8e-5 at 45 deg. 364 bytes, in flash on AVR. */
static const UNITS_ROM uint32_t TAN_Q24[91] = {
    0ul, 146413ul, 292847ul, 439327ul, 585873ul, 732509ul, 879257ul, 1026138ul, 1173177ul,
    1320396ul, 1467816ul, 1615462ul, 1763356ul, 1911522ul, 2059983ul, 2208762ul, 2357884ul,
    2507372ul, 2657250ul, 2807543ul, 2958276ul, 3109473ul, 3261160ul, 3413363ul, 3566107ul,
    3719419ul, 3873326ul, 4027853ul, 4183030ul, 4338883ul, 4495441ul, 4652734ul, 4810789ul,
    4969638ul, 5129310ul, 5289836ul, 5451248ul, 5613578ul, 5776859ul, 5941124ul, 6106407ul,
    6272744ul, 6440170ul, 6608721ul, 6778435ul, 6949350ul, 7121506ul, 7294941ul, 7469698ul,
    7645818ul, 7823344ul, 8002322ul, 8182795ul, 8364811ul, 8548419ul, 8733666ul, 8920604ul,
    9109285ul, 9299763ul, 9492092ul, 9686330ul, 9882535ul, 10080768ul, 10281091ul,
    10483568ul, 10688265ul, 10895251ul, 11104597ul, 11316375ul, 11530661ul, 11747533ul,
    11967072ul, 12189361ul, 12414487ul, 12642539ul, 12873611ul, 13107798ul, 13345200ul,
    13585922ul, 13830070ul, 14077756ul, 14329096ul, 14584211ul, 14843227ul, 15106273ul,
    15373486ul, 15645007ul, 15920984ul, 16201569ul, 16486924ul, 16777216ul
};

/* 2^48 / (2 pi): binary-angle units (2^32 per turn) per radian, times 2^16. */
#define BAM_PER_RAD_Q16 44798133900177ull
/* 18000 / pi * 65536: cdeg per radian in Q16. */
#define CDEG_PER_RAD_Q16 375493621ul
#define QUARTER_TURN_BAM 0x40000000ul
#define MAX_SUBSTEP_UM 32766L /* pieces <= 32767 um */

static struct {
    uint32_t heading_bam;
    int32_t x_mm;
    int32_t y_mm;
    int16_t x_rem_um; /* 0..999 */
    int16_t y_rem_um;
    uint8_t half_um;  /* differential: carried half micrometre of (l + r) / 2 */
    int32_t speed_mm_s;
    int32_t yaw_rate_cdeg_s;
    uint32_t k_yaw_diff; /* heading bam per um of (right - left), Q16 */
    uint32_t k_yaw_ack;  /* heading bam per um at tan = 1, Q16 */
    uint32_t k_rate_diff; /* cdeg/s per mm/s of (right - left), Q16 */
    uint32_t k_rate_ack;  /* cdeg/s per mm/s at tan = 1, Q16 */
} s_odom;

/* ---- table helpers ------------------------------------------------------ */

/* sin of a first-quadrant angle a in [0, 2^30] (2^30 = 90 deg), Q15. */
static int32_t quarter_sin(uint32_t a)
{
    uint8_t idx = (uint8_t)(a >> 24); /* 64 intervals */
    if (idx >= 64u) {
        return (int32_t)SIN_Q15[64];
    }
    uint16_t y0 = SIN_Q15[idx];
    uint16_t dy = (uint16_t)(SIN_Q15[idx + 1u] - y0); /* 0..804: table rises in the quadrant */
    uint16_t frac = (uint16_t)(a >> 8);             /* 16-bit position inside the interval */
    /* 16 x 16 -> 32 bit multiply (cheap on AVR) */
    return (int32_t)y0 + (int32_t)(((uint32_t)dy * frac + 32768u) >> 16);
}

int32_t odom_sin_q15(uint32_t angle_bam)
{
    uint32_t a = angle_bam & (QUARTER_TURN_BAM - 1u);
    /* top byte, then a small shift: avr-gcc -Os would loop 30 times on >> 30 */
    switch ((uint8_t)((uint8_t)(angle_bam >> 24) >> 6)) {
    case 0u:
        return quarter_sin(a);
    case 1u:
        return quarter_sin(QUARTER_TURN_BAM - a);
    case 2u:
        return -quarter_sin(a);
    default:
        return -quarter_sin(QUARTER_TURN_BAM - a);
    }
}

int32_t odom_cos_q15(uint32_t angle_bam)
{
    return odom_sin_q15(angle_bam + QUARTER_TURN_BAM);
}

int32_t odom_tan_q24(int32_t angle_cdeg)
{
    int32_t a = (int32_t)units_abs_u32(angle_cdeg);
    if (a > ODOM_STEER_LIMIT_CDEG) {
        a = ODOM_STEER_LIMIT_CDEG;
    }
    /* Table position in Q16 steps of 50 cdeg: a * 65536 / 50 = a * 1310.72,
     * as a * 1310 + a * 737 / 1024 (no division; within 1.2 / 65536 of a step). */
    uint32_t u = (uint32_t)a * 1310u + (((uint32_t)a * 737u + 512u) >> 10);
    uint8_t idx = (uint8_t)(u >> 16);
    uint16_t frac = (uint16_t)u;
    int32_t t;
    if (idx >= 90u || a >= ODOM_STEER_LIMIT_CDEG) {
        t = (int32_t)TAN_Q24[90];
    } else {
        uint32_t y0 = TAN_Q24[idx];
        uint32_t dy = TAN_Q24[idx + 1u] - y0; /* < 2^19 */
        /* dy * frac / 2^16 with 16 x 16 multiplies: dy = hi * 2^16 + lo */
        uint32_t lo = ((uint32_t)(uint16_t)dy * frac + 0x8000u) >> 16;
        uint32_t hi = (uint32_t)(uint16_t)(dy >> 16) * frac;
        t = (int32_t)(y0 + hi + lo);
    }
    return angle_cdeg < 0 ? -t : t;
}

uint32_t odom_bam_from_cdeg(int32_t angle_cdeg)
{
    int32_t c = units_wrap_cdeg(angle_cdeg);
    /* c * 2^32 / 36000, rounded; 64-bit division, used only when a pose is set. */
    int64_t num = (int64_t)c * 4294967296LL;
    int64_t q = (num >= 0 ? num + 18000 : num - 18000) / 36000;
    return (uint32_t)q;
}

int32_t odom_cdeg_from_bam(uint32_t angle_bam)
{
    /* floor((h * 36000 + 2^31) / 2^32), round to nearest, with h = hi * 2^16 + lo split so
     * that two 16 x 16 -> 32 multiplies replace a 64-bit one (every control tick, odom_get):
     * = floor((hi * 36000 + 2^15 + floor(lo * 36000 / 2^16)) / 2^16), exact. */
    int16_t hi = (int16_t)(angle_bam >> 16);
    uint16_t lo = (uint16_t)angle_bam;
    int32_t v = (int32_t)hi * 36000L + 32768L + (int32_t)(((uint32_t)lo * 36000u) >> 16);
    int32_t c = v >> 16; /* arithmetic shift: floor */
    return c <= -18000 ? 18000 : c;
}

/* ---- integration -------------------------------------------------------- */

/* Add d_um to a (mm, 0..999 um) pair. |d_um| <= 2^16. */
static void add_um(int32_t *mm, int16_t *rem_um, int32_t d_um)
{
    int16_t r;
    *mm += units_floordiv1000((int32_t)*rem_um + d_um, &r);
    *rem_um = r;
}

/* Round(d * k / 2^16) for a Q16 gain k. On the AVR a 64-bit multiply costs
 * ~250 cycles, so when |d| <= 65535 and k < 0x7FFF0000 (true for every
 * track / wheelbase >= 21 mm) two 32-bit multiplies do it exactly:
 * d * k = d * k_hi * 2^16 + d * k_lo. */
static int32_t mul_q16(int32_t d, uint32_t k)
{
    uint32_t m = units_abs_u32(d);
    uint32_t r;
    if (m <= 0xFFFFu && k < 0x7FFF0000u) {
        /* 16 x 16 -> 32 bit operands: avr-gcc's short widening multiply, not __mulsi3 */
        uint16_t m16 = (uint16_t)m;
        r = (uint32_t)m16 * (uint16_t)(k >> 16) + (((uint32_t)m16 * (uint16_t)k + 0x8000u) >> 16);
    } else {
        uint64_t w = ((uint64_t)m * k + 0x8000u) >> 16;
        r = w > 0x7FFFFFFFu ? 0x7FFFFFFFu : (uint32_t)w;
    }
    return d < 0 ? -(int32_t)r : (int32_t)r;
}

/* Round(d * c / 2^15) for |d| <= 32767, |c| <= 32768 (|d * c| < 2^30).
 * Shift left by one and take the top half: a 16-bit shift is a register
 * move on the AVR, a 15-bit one a loop. */
static int32_t mul_q15(int32_t d, int32_t c)
{
    if (c == 32768L) {
        return d; /* sin 90 deg, the one factor beyond int16: round(d * 2^15 / 2^15) */
    }
    /* 16 x 16 -> 32 bit operands (short widening multiply on the AVR) */
    uint32_t p = (uint32_t)((int32_t)(int16_t)d * (int16_t)c + 16384L) << 1;
    return (int32_t)p >> 16;
}

/* v / 2 rounded toward zero, without the division call avr-gcc -Os emits. */
static int32_t half_i32(int32_t v)
{
    return (v + (int32_t)((uint32_t)v >> 31)) >> 1;
}

static int32_t clamp_i32(int32_t v, int32_t lim)
{
    return v > lim ? lim : (v < -lim ? -lim : v);
}

/* One sub-step: travel ds_um (|ds_um| <= 32767) at the midpoint heading,
 * heading change dth_bam (signed). */
static void substep(int32_t ds_um, int32_t dth_bam)
{
    uint32_t mid = s_odom.heading_bam + (uint32_t)half_i32(dth_bam);
    if (ds_um != 0) {
        int32_t dx = mul_q15(ds_um, odom_cos_q15(mid));
        int32_t dy = mul_q15(ds_um, odom_sin_q15(mid));
        add_um(&s_odom.x_mm, &s_odom.x_rem_um, dx);
        add_um(&s_odom.y_mm, &s_odom.y_rem_um, dy);
    }
    s_odom.heading_bam += (uint32_t)dth_bam;
}

/* Smallest shift so that |a| >> shift and |b| >> shift fit a sub-step. */
static uint8_t split_shift(int32_t a, int32_t b)
{
    uint32_t ma = units_abs_u32(a);
    uint32_t mb = units_abs_u32(b);
    uint32_t m = ma > mb ? ma : mb;
    uint8_t sh = 0u;
    while ((m >> sh) > (uint32_t)MAX_SUBSTEP_UM) {
        sh++;
    }
    return sh;
}

/* Piece i of n = 2^sh pieces of v: floor(v / n), plus one for the first
 * (v mod n) pieces, so the pieces add up to v exactly and each is <= 32767. */
static int32_t piece(int32_t v, uint8_t sh, uint32_t i)
{
    int32_t q = v >> sh; /* floor */
    uint32_t rem = (uint32_t)(v - (int32_t)((uint32_t)q << sh));
    return q + (i < rem ? 1 : 0);
}

static void diff_substep(int32_t l_um, int32_t r_um)
{
    /* Centre travel (l + r) / 2, keeping the odd half micrometre. */
    int32_t sum = l_um + r_um + (int32_t)s_odom.half_um;
    s_odom.half_um = (uint8_t)(sum & 1);
    int32_t ds = sum >> 1;
    /* dth = (r - l) / track, in bam: |r - l| <= 2^16. */
    substep(ds, mul_q16(r_um - l_um, s_odom.k_yaw_diff));
}

static void ack_substep(int32_t ds_um, uint32_t kappa_mag_q16, bool left)
{
    /* dth = ds * curvature, in bam: |ds| <= 2^15. */
    int32_t dth = mul_q16(ds_um, kappa_mag_q16);
    substep(ds_um, left ? dth : -dth);
}

/* ---- public ------------------------------------------------------------- */

bool odom_init(const odom_cfg_t *cfg)
{
    uint16_t track_mm = ODOM_DEFAULT_TRACK_MM;
    uint16_t wheelbase_mm = ODOM_DEFAULT_WHEELBASE_MM;
    bool ok = true;
    if (cfg != NULL) {
        if (cfg->model > (uint8_t)ODOM_MODEL_ACKERMANN) {
            ok = false;
        }
        /* Below 11 mm the Q16 heading gain would not fit 32 bits. */
        if (cfg->track_mm >= 11u) {
            track_mm = cfg->track_mm;
        } else if (cfg->track_mm != 0u) {
            ok = false;
        }
        if (cfg->wheelbase_mm >= 11u) {
            wheelbase_mm = cfg->wheelbase_mm;
        } else if (cfg->wheelbase_mm != 0u) {
            ok = false;
        }
    }
    s_odom.heading_bam = 0u;
    s_odom.x_mm = 0;
    s_odom.y_mm = 0;
    s_odom.x_rem_um = 0;
    s_odom.y_rem_um = 0;
    s_odom.half_um = 0u;
    s_odom.speed_mm_s = 0;
    s_odom.yaw_rate_cdeg_s = 0;
    /* Init-time 64-bit divisions, rounded (the mm * 1000 divisors fit 32 bits). */
    s_odom.k_yaw_diff = (uint32_t)units_div_round_u64(BAM_PER_RAD_Q16, (uint32_t)track_mm * 1000u);
    s_odom.k_yaw_ack = (uint32_t)units_div_round_u64(BAM_PER_RAD_Q16, (uint32_t)wheelbase_mm * 1000u);
    s_odom.k_rate_diff = units_div_round_u32(CDEG_PER_RAD_Q16, track_mm);
    s_odom.k_rate_ack = units_div_round_u32(CDEG_PER_RAD_Q16, wheelbase_mm);
    return ok;
}

void odom_set_pose(int32_t x_mm, int32_t y_mm, int32_t heading_cdeg)
{
    s_odom.x_mm = x_mm;
    s_odom.y_mm = y_mm;
    s_odom.x_rem_um = 0;
    s_odom.y_rem_um = 0;
    s_odom.half_um = 0u;
    s_odom.heading_bam = odom_bam_from_cdeg(heading_cdeg);
}

void odom_update_diff(int32_t left_um, int32_t right_um, int32_t left_mm_s, int32_t right_mm_s)
{
    uint8_t sh = split_shift(left_um, right_um);
    uint32_t n = (uint32_t)1u << sh;
    for (uint32_t i = 0; i < n; i++) {
        diff_substep(piece(left_um, sh, i), piece(right_um, sh, i));
    }
    /* Speeds beyond +-65 m/s are not physical: clamp so 32-bit math holds. */
    int32_t vl = clamp_i32(left_mm_s, 65535L);
    int32_t vr = clamp_i32(right_mm_s, 65535L);
    s_odom.speed_mm_s = half_i32(vl + vr);
    s_odom.yaw_rate_cdeg_s = mul_q16(vr - vl, s_odom.k_rate_diff);
}

void odom_update_ackermann(int32_t rear_um, int32_t steer_cdeg, int32_t rear_mm_s)
{
    int32_t tan_q24 = odom_tan_q24(steer_cdeg);
    bool left = tan_q24 >= 0;
    uint32_t tan_mag = (uint32_t)(left ? tan_q24 : -tan_q24);
    /* Once per call: curvature tan(steer) / L as heading bam per um (Q16),
     * and yaw rate per mm/s (Q16); |tan| <= 2^24 so 64 bits suffice. */
    uint32_t kappa_q16 = (uint32_t)(((uint64_t)tan_mag * s_odom.k_yaw_ack + (1ul << 23)) >> 24);
    uint32_t krate_q16 = (uint32_t)(((uint64_t)tan_mag * s_odom.k_rate_ack + (1ul << 23)) >> 24);
    uint8_t sh = split_shift(rear_um, 0);
    uint32_t n = (uint32_t)1u << sh;
    for (uint32_t i = 0; i < n; i++) {
        ack_substep(piece(rear_um, sh, i), kappa_q16, left);
    }
    s_odom.speed_mm_s = rear_mm_s;
    int32_t w = mul_q16(clamp_i32(rear_mm_s, 65535L), krate_q16);
    s_odom.yaw_rate_cdeg_s = left ? w : -w;
}

void odom_get(odom_pose_t *out)
{
    if (out == NULL) {
        return;
    }
    out->x_mm = s_odom.x_mm;
    out->y_mm = s_odom.y_mm;
    out->heading_cdeg = odom_cdeg_from_bam(s_odom.heading_bam);
    out->speed_mm_s = s_odom.speed_mm_s;
    out->yaw_rate_cdeg_s = s_odom.yaw_rate_cdeg_s;
}

void odom_behaviour_inputs(behaviour_in_t *in)
{
    in->x_mm = s_odom.x_mm;
    in->y_mm = s_odom.y_mm;
    in->heading_cdeg = (int16_t)odom_cdeg_from_bam(s_odom.heading_bam);
    in->speed_mm_s = (int16_t)s_odom.speed_mm_s;
}

uint32_t odom_heading_bam(void)
{
    return s_odom.heading_bam;
}
