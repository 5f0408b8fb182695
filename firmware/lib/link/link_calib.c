#include "link_calib.h"

#include <string.h>

static uint16_t dist(uint16_t pwm, uint16_t neutral)
{
    return pwm > neutral ? (uint16_t)(pwm - neutral) : (uint16_t)(neutral - pwm);
}

/* Insertion by distance from neutral (outward order). */
static bool side_add(calib_side_t *side, uint16_t neutral, uint16_t pwm, int16_t value)
{
    if (side->n >= CALIB_MAX_POINTS) {
        return false;
    }
    uint8_t i = side->n;
    while (i > 0u && dist(side->pt[i - 1u].pwm, neutral) > dist(pwm, neutral)) {
        side->pt[i] = side->pt[i - 1u];
        i--;
    }
    side->pt[i].pwm = pwm;
    side->pt[i].value = value;
    side->n++;
    return true;
}

uint8_t link_calib_from_msg(const mavlink_agnav_calib_table_t *msg, calib_table_t *out)
{
    memset(out, 0, sizeof *out);
    out->neutral_pwm = msg->neutral_pwm;
    uint8_t n = msg->n_points > 16u ? 16u : msg->n_points;
    int8_t pos_above = 0; /* +1: positive side lies above neutral, -1 below, 0 unknown */
    int8_t neg_above = 0;
    for (uint8_t i = 0; i < n; i++) {
        int8_t above = msg->pwm[i] > msg->neutral_pwm ? 1 : -1;
        if (msg->value[i] > 0 && pos_above == 0) {
            pos_above = above;
        } else if (msg->value[i] < 0 && neg_above == 0) {
            neg_above = above;
        }
    }
    for (uint8_t i = 0; i < n; i++) {
        int16_t v = msg->value[i];
        int8_t above = msg->pwm[i] > msg->neutral_pwm ? 1 : -1;
        calib_side_t *side;
        if (v == 0 && msg->pwm[i] == msg->neutral_pwm) {
            /* The neutral point may start either side (or both): first to pos, then neg. */
            bool pos_has = out->pos.n > 0u && out->pos.pt[0].pwm == out->neutral_pwm;
            side = pos_has ? &out->neg : &out->pos;
        } else if (v > 0 || (v == 0 && pos_above == above)) {
            side = &out->pos;
        } else if (v < 0 || (v == 0 && neg_above == above)) {
            side = &out->neg;
        } else {
            return AGNAV_CALIB_BAD_TABLE;
        }
        if (!side_add(side, out->neutral_pwm, msg->pwm[i], v)) {
            return AGNAV_CALIB_BAD_TABLE;
        }
    }
    return 0u;
}

void link_calib_to_msg(uint8_t table_id, const calib_table_t *t, mavlink_agnav_calib_table_t *out)
{
    memset(out, 0, sizeof *out);
    out->table_id = table_id;
    out->neutral_pwm = t->neutral_pwm;
    out->dead_band_low_pwm = t->neutral_pwm;
    out->dead_band_high_pwm = t->neutral_pwm;
    uint8_t n = 0;
    const calib_side_t *sides[2] = {&t->pos, &t->neg};
    for (uint8_t s = 0; s < 2u; s++) {
        for (uint8_t i = 0; i < sides[s]->n && n < 16u; i++) {
            uint16_t pwm = sides[s]->pt[i].pwm;
            /* insertion sort by pwm */
            uint8_t k = n;
            while (k > 0u && out->pwm[k - 1u] > pwm) {
                out->pwm[k] = out->pwm[k - 1u];
                out->value[k] = out->value[k - 1u];
                k--;
            }
            out->pwm[k] = pwm;
            out->value[k] = sides[s]->pt[i].value;
            n++;
        }
        if (sides[s]->n > 0u) {
            uint16_t inner = sides[s]->pt[0].pwm;
            if (inner < t->neutral_pwm) {
                out->dead_band_low_pwm = inner;
            } else {
                out->dead_band_high_pwm = inner;
            }
        }
    }
    out->n_points = n;
}

uint8_t link_calib_result(calib_status_t status)
{
    switch (status) {
    case CALIB_OK:
        return AGNAV_CALIB_ACCEPTED;
    case CALIB_E_NON_MONOTONE:
        return AGNAV_CALIB_NON_MONOTONE;
    case CALIB_E_PWM_RANGE:
    case CALIB_E_VALUE_RANGE:
        return AGNAV_CALIB_OUT_OF_RANGE;
    case CALIB_E_TOO_FEW_POINTS:
        return AGNAV_CALIB_TOO_FEW_POINTS;
    case CALIB_E_NO_SPACE:
        return AGNAV_CALIB_STORAGE_ERROR;
    default:
        return AGNAV_CALIB_BAD_TABLE;
    }
}
