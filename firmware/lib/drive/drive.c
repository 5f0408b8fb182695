#include "drive.h"

#include "calib.h"
#include "hal.h"
#include "units.h"

static drive_cfg_t s_cfg;
static drive_output_t s_out;

uint16_t drive_servo_us_from_byte(uint16_t byte)
{
    if (byte > 255u) {
        byte = 255u;
    }
    return (uint16_t)(1000u + ((uint32_t)byte * 1000u + 127u) / 255u);
}

uint16_t drive_esc_us_from_byte(uint16_t byte, int8_t dir)
{
    if (byte > 255u) {
        byte = 255u;
    }
    uint16_t delta = (uint16_t)(((uint32_t)byte * 500u + 127u) / 255u);
    if (dir < 0) {
        return (uint16_t)(1500u - delta);
    }
    return dir > 0 ? (uint16_t)(1500u + delta) : 1500u;
}

void drive_init(const drive_cfg_t *cfg)
{
    s_cfg = *cfg;
    if (s_cfg.track_mm == 0u) {
        s_cfg.track_mm = 191u;
    }
    if (s_cfg.spin_mm_s == 0u) {
        s_cfg.spin_mm_s = 300u;
    }
    if (s_cfg.spin_below_mm_s == 0u) {
        s_cfg.spin_below_mm_s = 100u;
    }
    drive_stop();
}

static int8_t sign16(int16_t v) { return v > 0 ? 1 : (v < 0 ? -1 : 0); }

static uint8_t duty_from(uint8_t table, int16_t speed_mm_s)
{
    int32_t mag = (int32_t)units_abs_u32(speed_mm_s);
    uint16_t b = calib_pwm_from_value(table, mag);
    return (uint8_t)(b > 255u ? 255u : b);
}

void drive_apply(int16_t steer_cdeg, int16_t speed_mm_s)
{
    s_out.direction = sign16(speed_mm_s);
    if (s_cfg.kind == DRIVE_ACKERMANN) {
        uint16_t steer_b = calib_pwm_from_value(CALIB_STEER, steer_cdeg);
        int32_t mag = (int32_t)units_abs_u32(speed_mm_s);
        uint16_t speed_b = calib_pwm_from_value(CALIB_SPEED, mag);
        s_out.steer_us = drive_servo_us_from_byte(steer_b);
        s_out.throttle_us = drive_esc_us_from_byte(speed_b, s_out.direction);
        hal_servo_write_us(HAL_SERVO_STEER, s_out.steer_us);
        hal_servo_write_us(HAL_SERVO_THROTTLE, s_out.throttle_us);
        return;
    }
    /* Differential: v_side = v (1 -+ tan(phi) / 2), i.e. omega = v tan(phi) / track.
     * Shifts and multiplies only (a 32-bit division costs ~600 cycles on the AVR). */
    int32_t phi_q12 = ((int32_t)steer_cdeg * 183L) >> 8;          /* rad in Q12: 4096 pi / 18000 = 0.7149 ~ 183/256 */
    int32_t phi3_q12 = (((phi_q12 * phi_q12) >> 12) * phi_q12) >> 12;
    int32_t tan_q12 = phi_q12 + ((phi3_q12 * 21845L) >> 16);        /* tan x ~ x + x^3/3, < 1.5 % to 30 deg */
    int32_t half = ((int32_t)speed_mm_s * tan_q12) >> 13;           /* v tan(phi) / 2 */
    int32_t mag = (int32_t)units_abs_u32(speed_mm_s);
    if (mag < (int32_t)s_cfg.spin_below_mm_s) {
        /* Spin on the spot: steer / 4500 cdeg * spin_mm_s; 1/4500 ~ 233 / 2^20. */
        half = ((int32_t)steer_cdeg * (int32_t)s_cfg.spin_mm_s * 233L) >> 20;
    }
    int32_t l = (int32_t)speed_mm_s - half;
    int32_t r = (int32_t)speed_mm_s + half;
    s_out.left_mm_s = (int16_t)(l > 32767 ? 32767 : (l < -32767 ? -32767 : l));
    s_out.right_mm_s = (int16_t)(r > 32767 ? 32767 : (r < -32767 ? -32767 : r));
    s_out.left_duty = duty_from(CALIB_SPEED_LEFT, s_out.left_mm_s);
    s_out.right_duty = duty_from(CALIB_SPEED_RIGHT, s_out.right_mm_s);
    hal_pwm_write_duty(0u, s_out.left_duty, s_out.left_mm_s < 0);
    hal_pwm_write_duty(1u, s_out.right_duty, s_out.right_mm_s < 0);
}

void drive_apply_raw(uint16_t steer_pwm, uint16_t speed_pwm, int8_t dir)
{
    s_out.direction = dir;
    if (s_cfg.kind == DRIVE_ACKERMANN) {
        s_out.steer_us = drive_servo_us_from_byte(steer_pwm);
        s_out.throttle_us = drive_esc_us_from_byte(speed_pwm, dir);
        hal_servo_write_us(HAL_SERVO_STEER, s_out.steer_us);
        hal_servo_write_us(HAL_SERVO_THROTTLE, s_out.throttle_us);
    } else {
        uint8_t d = (uint8_t)(speed_pwm > 255u ? 255u : speed_pwm);
        s_out.left_duty = s_out.right_duty = d;
        hal_pwm_write_duty(0u, d, dir < 0);
        hal_pwm_write_duty(1u, d, dir < 0);
    }
}

static uint8_t byte_of(uint16_t pwm) { return (uint8_t)(pwm > 255u ? 255u : pwm); }

void drive_raw_physical(uint16_t steer_pwm, uint16_t speed_pwm, int8_t dir, int16_t *steer_cdeg, int16_t *speed_mm_s)
{
    uint8_t v_b = byte_of(speed_pwm);
    int32_t v;
    int32_t steer = 0;
    if (s_cfg.kind == DRIVE_ACKERMANN) {
        steer = calib_value_from_pwm(CALIB_STEER, byte_of(steer_pwm));
        v = calib_value_from_pwm(CALIB_SPEED, v_b);
    } else {
        int32_t r = calib_value_from_pwm(CALIB_SPEED_RIGHT, v_b);
        v = calib_value_from_pwm(CALIB_SPEED_LEFT, v_b);
        v = r > v ? r : v;
    }
    if (v < 0) {
        v = -v; /* the magnitude: the direction comes from dir, as in drive_apply_raw */
    }
    if (v == 0 && v_b != 0u) {
        v = 1; /* dead band */
    }
    *steer_cdeg = (int16_t)steer;
    *speed_mm_s = (int16_t)(dir < 0 ? -v : v);
}

void drive_stop(void)
{
    s_out.direction = 0;
    s_out.left_mm_s = s_out.right_mm_s = 0;
    s_out.left_duty = s_out.right_duty = 0u;
    s_out.steer_us = drive_servo_us_from_byte(calib_pwm_from_value(CALIB_STEER, 0));
    s_out.throttle_us = 1500u;
    hal_servo_write_us(HAL_SERVO_STEER, s_out.steer_us);
    hal_servo_write_us(HAL_SERVO_THROTTLE, s_out.throttle_us);
    hal_pwm_write_duty(0u, 0u, false);
    hal_pwm_write_duty(1u, 0u, false);
}

const drive_output_t *drive_output(void) { return &s_out; }

static bool side_fits(const calib_side_t *s)
{
    for (uint8_t i = 0; i < s->n && i < CALIB_MAX_POINTS; i++) {
        if (s->pt[i].pwm > 255u) {
            return false;
        }
    }
    return true;
}

bool drive_table_fits(uint8_t id, const calib_table_t *t)
{
    if (t->neutral_pwm > 255u || (id != (uint8_t)CALIB_STEER && t->neutral_pwm != 0u)) {
        return false;
    }
    return side_fits(&t->pos) && side_fits(&t->neg);
}
