/*
 * Actuator calibration tables: lookup, validation, EEPROM storage.
 * See calib.h for the table shape and the storage layout.
 */
#include "calib.h"

#include <stddef.h>

#include "crc16.h"
#include "hal.h"
#include "units.h"

/* ---- defaults from the reference car (ref 003, section 6.5) --------------
 *
 * Steering. Least-squares fits over table 6.1 (PWM given in hex there):
 *   above the centre: |phi| deg =  0.6502 * PWM - 86.477  (rows 0x95..0xA5)
 *   below the centre: |phi| deg = -0.6717 * PWM + 89.698  (rows 0x60..0x75)
 * The signs were lost in the text conversion; reconstructed from the table
 * rows, e.g. PWM 0x95 = 149 -> 10.4 deg and 0x60 = 96 -> 24.6 deg. The
 * thesis labels the first fit "turning left" and the second "turning
 * right", so PWM above the centre is a left turn = positive steering under
 * REP-103; the pos side therefore lies above neutral.
 * Neutral: the fits cross zero at 133.0 and 133.5; the thesis used 132 for
 * straight driving; we take 133 (both fits within 0.4 deg there).
 * Saturation at 24.6 deg, the largest angle measured.
 *   left:  (133, 0) (170, 24.06 deg) (171, 24.6 deg)
 *   right: (133, 0) (130, -2.38) (97, -24.54) (96, -24.6): the fit from 130
 *          outwards; 130..133 ramps to the common neutral.
 *
 * Speed. Table 6.2 and its fit v cm/s = 2.038 * PWM - 22.636 over
 * 43.5..200 cm/s (PWM 0x20..0x70). Below v = 43.5 cm/s (PWM 32.45) the car
 * does not move: dead band up to PWM 32, first point PWM 33 = 446 mm/s, last
 * PWM 109 = 1995 mm/s (the fit's 200 cm/s is at 109.2). Neutral 0. No
 * reverse data: the negative side is empty (sign-magnitude). Differential
 * robots replace both speed tables with their own measurements. */
static const UNITS_ROM calib_table_t CALIB_DEFAULTS[CALIB_TABLE_COUNT] = {
    /* CALIB_STEER */
    {133u,
     {3u, {{133u, 0}, {170u, 2406}, {171u, 2460}}},
     {4u, {{133u, 0}, {130u, -238}, {97u, -2454}, {96u, -2460}}}},
    /* CALIB_SPEED_LEFT */
    {0u, {2u, {{33u, 446}, {109u, 1995}}}, {0u, {{0u, 0}}}},
    /* CALIB_SPEED_RIGHT */
    {0u, {2u, {{33u, 446}, {109u, 1995}}}, {0u, {{0u, 0}}}},
};

static calib_table_t s_tables[CALIB_TABLE_COUNT];
static uint8_t s_health;
static calib_status_t s_last_load;

/* ---- lookup --------------------------------------------------------------- */

/* |a - b| */
static uint16_t dist_u16(uint16_t a, uint16_t b) { return (uint16_t)units_abs_u32((int32_t)a - (int32_t)b); }

/* True if the pos side lies above neutral (decided by its last point). */
static bool pos_above(const calib_table_t *t)
{
    return t->pos.n > 0u && t->pos.pt[t->pos.n - 1u].pwm > t->neutral_pwm;
}

/* One side's piecewise-linear map, either way: to_value looks up by the distance of the pwm from
 * neutral and gives the value; otherwise by |value| and gives the pwm. Below the first point: the
 * dead band (value 0), or slower than the actuator can go (neutral: stop rather than go faster than
 * asked); beyond the last point: saturation. One function for both directions keeps the AVR build
 * small. Validated tables keep every key and output within 16 bits (pwm <= 3000, |value| <= 10000,
 * one sign per side); the product of a step stays below 2^31. */
__attribute__((noinline)) static int32_t side_lookup(const calib_side_t *s, uint16_t neutral, bool to_value, uint16_t x)
{
    int32_t prev_o = to_value ? 0 : (int32_t)neutral;
    uint16_t prev_k = 0u;
    for (uint8_t i = 0; i < s->n; i++) {
        const calib_point_t *p = &s->pt[i];
        uint16_t k = to_value ? dist_u16(p->pwm, neutral) : (uint16_t)units_abs_u32(p->value);
        int32_t o = to_value ? (int32_t)p->value : (int32_t)p->pwm;
        if (x < k) {
            return i == 0u ? prev_o
                           : prev_o + units_div_round_i32((o - prev_o) * (int32_t)(x - prev_k), (int32_t)(k - prev_k));
        }
        prev_k = k;
        prev_o = o;
    }
    return prev_o;
}

int32_t calib_table_value(const calib_table_t *t, uint16_t pwm)
{
    if (t == NULL || pwm == t->neutral_pwm) {
        return 0;
    }
    bool above = pwm > t->neutral_pwm;
    return side_lookup(above == pos_above(t) ? &t->pos : &t->neg, t->neutral_pwm, true, dist_u16(pwm, t->neutral_pwm));
}

uint16_t calib_table_pwm(const calib_table_t *t, int32_t value)
{
    if (t == NULL) {
        return 0u;
    }
    if (value == 0) {
        return t->neutral_pwm;
    }
    const calib_side_t *s = value > 0 ? &t->pos : &t->neg;
    if (s->n == 0u) {
        s = &t->pos; /* sign-magnitude: the output stage sets the direction */
    }
    uint32_t mag = units_abs_u32(value); /* defined for INT32_MIN too */
    return (uint16_t)side_lookup(s, t->neutral_pwm, false, (uint16_t)(mag > 65535u ? 65535u : mag));
}

int32_t calib_value_from_pwm(uint8_t id, uint16_t pwm)
{
    return id < (uint8_t)CALIB_TABLE_COUNT ? calib_table_value(&s_tables[id], pwm) : 0;
}

uint16_t calib_pwm_from_value(uint8_t id, int32_t value)
{
    return id < (uint8_t)CALIB_TABLE_COUNT ? calib_table_pwm(&s_tables[id], value) : 0u;
}

/* ---- validation ----------------------------------------------------------- */

/* sign: +1 for the pos side, -1 for neg; above: side lies above neutral. */
static calib_status_t check_side(const calib_side_t *s, uint16_t neutral, int8_t sign, bool above,
                                 int32_t limit)
{
    if (s->n > CALIB_MAX_POINTS) {
        return CALIB_E_TOO_MANY_POINTS;
    }
    if (s->n == 1u) {
        return CALIB_E_TOO_FEW_POINTS;
    }
    int32_t prev_d = -1;
    int32_t prev_m = -1;
    for (uint8_t i = 0; i < s->n; i++) {
        const calib_point_t *p = &s->pt[i];
        if (p->pwm > CALIB_PWM_MAX) {
            return CALIB_E_PWM_RANGE;
        }
        if ((int32_t)units_abs_u32(p->value) > limit) {
            return CALIB_E_VALUE_RANGE;
        }
        if ((sign > 0 && p->value < 0) || (sign < 0 && p->value > 0)) {
            return CALIB_E_WRONG_SIDE;
        }
        if (p->pwm == neutral) {
            if (i != 0u || p->value != 0) {
                return CALIB_E_WRONG_SIDE; /* only a zero first point may sit at neutral */
            }
        } else if ((p->pwm > neutral) != above) {
            return CALIB_E_WRONG_SIDE;
        }
        int32_t d = dist_u16(p->pwm, neutral);
        int32_t m = (int32_t)units_abs_u32(p->value);
        if (d <= prev_d || m <= prev_m) {
            return CALIB_E_NON_MONOTONE;
        }
        prev_d = d;
        prev_m = m;
    }
    return CALIB_OK;
}

calib_status_t calib_validate(uint8_t id, const calib_table_t *t)
{
    if (id >= (uint8_t)CALIB_TABLE_COUNT || t == NULL) {
        return CALIB_E_BAD_ID;
    }
    bool steer = id == (uint8_t)CALIB_STEER;
    int32_t limit = steer ? CALIB_ANGLE_LIMIT_CDEG : CALIB_SPEED_LIMIT_MM_S;
    if (t->neutral_pwm > CALIB_PWM_MAX) {
        return CALIB_E_PWM_RANGE;
    }
    if (t->pos.n > CALIB_MAX_POINTS || t->neg.n > CALIB_MAX_POINTS) {
        return CALIB_E_TOO_MANY_POINTS;
    }
    /* Both sides are needed for steering; a speed table may be one-sided. */
    if (t->pos.n < 2u || (steer && t->neg.n < 2u)) {
        return CALIB_E_TOO_FEW_POINTS;
    }
    if (t->pos.pt[t->pos.n - 1u].pwm == t->neutral_pwm) {
        return CALIB_E_WRONG_SIDE;
    }
    bool above = pos_above(t);
    calib_status_t r = check_side(&t->pos, t->neutral_pwm, 1, above, limit);
    if (r == CALIB_OK) {
        r = check_side(&t->neg, t->neutral_pwm, -1, !above, limit);
    }
    return r;
}

/* ---- active tables -------------------------------------------------------- */

static void load_defaults(void)
{
    for (uint8_t i = 0; i < (uint8_t)CALIB_TABLE_COUNT; i++) {
        s_tables[i] = CALIB_DEFAULTS[i]; /* flash -> RAM copy on AVR */
    }
    s_health |= CALIB_DEFAULTED;
}

void calib_init(void)
{
    s_health = 0u;
    s_last_load = CALIB_OK;
    load_defaults();
}

uint8_t calib_health(void) { return s_health; }
calib_status_t calib_last_load_status(void) { return s_last_load; }

calib_status_t calib_set_table(uint8_t id, const calib_table_t *t)
{
    calib_status_t r = calib_validate(id, t);
    if (r == CALIB_OK) {
        s_tables[id] = *t;
    }
    return r;
}

bool calib_get_table(uint8_t id, calib_table_t *out)
{
    if (id >= (uint8_t)CALIB_TABLE_COUNT || out == NULL) {
        return false;
    }
    *out = s_tables[id];
    return true;
}

bool calib_get_default(uint8_t id, calib_table_t *out)
{
    if (id >= (uint8_t)CALIB_TABLE_COUNT || out == NULL) {
        return false;
    }
    *out = CALIB_DEFAULTS[id];
    return true;
}

void calib_use_default(uint8_t id)
{
    if (id < (uint8_t)CALIB_TABLE_COUNT) {
        s_tables[id] = CALIB_DEFAULTS[id];
        s_health |= CALIB_DEFAULTED;
    }
}

/* ---- storage -------------------------------------------------------------- */

#define HDR_BYTES 6u
#define PAYLOAD_BYTES (3u * CALIB_TABLE_BYTES)

static uint16_t get_u16(const uint8_t *b) { return (uint16_t)(b[0] | ((uint16_t)b[1] << 8)); }

/* Not inlined: boot and load only. */
__attribute__((noinline)) static void decode_table(const uint8_t *b, calib_table_t *t)
{
    t->neutral_pwm = get_u16(b);
    uint8_t k = 2u;
    for (uint8_t side = 0; side < 2u; side++) {
        calib_side_t *s = side == 0u ? &t->pos : &t->neg;
        s->n = b[k++];
        for (uint8_t i = 0; i < CALIB_MAX_POINTS; i++) {
            s->pt[i].pwm = get_u16(&b[k]);
            s->pt[i].value = (int16_t)get_u16(&b[k + 2u]);
            k = (uint8_t)(k + 4u);
        }
    }
}

uint8_t calib_record_byte(uint16_t pos)
{
    uint16_t v;
    uint8_t k;
    if (pos < HDR_BYTES) { /* magic u16, layout version u8, table count u8, payload length u16 */
        v = pos < 2u ? CALIB_MAGIC
            : pos < 4u ? (uint16_t)(CALIB_LAYOUT_VERSION | ((uint16_t)CALIB_TABLE_COUNT << 8)) : PAYLOAD_BYTES;
        k = (uint8_t)pos;
    } else {
        pos = (uint16_t)(pos - HDR_BYTES);
        const calib_table_t *t = &s_tables[pos / CALIB_TABLE_BYTES];
        k = (uint8_t)(pos % CALIB_TABLE_BYTES);
        if (k < 2u) {
            v = t->neutral_pwm;
        } else { /* each side: n u8, then CALIB_MAX_POINTS x {pwm u16, value i16}, unused points 0 */
            k = (uint8_t)(k - 2u);
            const calib_side_t *side = k < 33u ? &t->pos : &t->neg;
            k = (uint8_t)(k % 33u);
            if (k == 0u) {
                return side->n;
            }
            k = (uint8_t)(k - 1u);
            uint8_t i = (uint8_t)(k / 4u);
            v = i >= side->n ? 0u : (k & 2u) ? (uint16_t)side->pt[i].value : side->pt[i].pwm;
        }
    }
    return (uint8_t)(v >> ((k & 1u) ? 8u : 0u));
}

/* Check the record at addr; when apply is true also copy the tables into the active set (only called
 * after a full check passed). */
static calib_status_t read_record(uint16_t addr, bool apply)
{
    uint8_t h[HDR_BYTES];
    uint8_t b[CALIB_TABLE_BYTES];
    calib_table_t t;

    if ((uint32_t)addr + CALIB_RECORD_BYTES > (uint32_t)hal_eeprom_size()) {
        return CALIB_E_NO_SPACE;
    }
    hal_eeprom_read(addr, h, HDR_BYTES);
    bool erased = true;
    for (uint8_t i = 0; i < HDR_BYTES; i++) {
        erased = erased && h[i] == 0xFFu;
    }
    if (erased) {
        return CALIB_E_ERASED;
    }
    if (get_u16(h) != CALIB_MAGIC) {
        return CALIB_E_BAD_MAGIC;
    }
    if (h[2] != CALIB_LAYOUT_VERSION) {
        return CALIB_E_BAD_VERSION;
    }
    if (h[3] != (uint8_t)CALIB_TABLE_COUNT || get_u16(&h[4]) != PAYLOAD_BYTES) {
        return CALIB_E_BAD_LENGTH;
    }
    uint16_t crc = crc16_ccitt_false(h, HDR_BYTES);
    calib_status_t table_status = CALIB_OK;
    for (uint8_t id = 0; id < (uint8_t)CALIB_TABLE_COUNT; id++) {
        hal_eeprom_read((uint16_t)(addr + HDR_BYTES + id * CALIB_TABLE_BYTES), b, CALIB_TABLE_BYTES);
        crc = crc16_ccitt_false_update(crc, b, CALIB_TABLE_BYTES);
        decode_table(b, &t);
        if (calib_validate(id, &t) != CALIB_OK) {
            table_status = CALIB_E_BAD_TABLE;
        } else if (apply) {
            s_tables[id] = t;
        }
    }
    uint8_t c[2];
    hal_eeprom_read((uint16_t)(addr + HDR_BYTES + PAYLOAD_BYTES), c, 2u);
    if (get_u16(c) != crc) {
        return CALIB_E_BAD_CRC;
    }
    return table_status;
}

calib_status_t calib_load(void)
{
    uint16_t addr = CALIB_EEPROM_ADDR;
    calib_status_t r = read_record(addr, false);
    if (r != CALIB_OK && read_record(CALIB_COPY_ADDR, false) == CALIB_OK) {
        addr = CALIB_COPY_ADDR; /* a save cut short in the main slot: the copy is whole */
        r = CALIB_OK;
    }
    if (r == CALIB_OK) {
        (void)read_record(addr, true);
        s_health = (uint8_t)(s_health & ~CALIB_DEFAULTED);
    } else {
        load_defaults();
    }
    s_last_load = r;
    return r;
}

void calib_saved(bool ok)
{
    s_health = ok ? (uint8_t)(s_health & ~(CALIB_DEFAULTED | CALIB_SAVE_FAILED)) : (uint8_t)(s_health | CALIB_SAVE_FAILED);
}
