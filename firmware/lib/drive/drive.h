/*
 * Output stage: physical drive commands (cdeg, mm/s) -> actuator commands,
 * through the calibration tables, for the two platform kinds AgNav supports.
 *
 * Calibration tables use the reference car's 8-bit command unit (ref 003:
 * neutral steering 133, speed dead band below ~32). The output stage maps that
 * byte to what the hardware takes:
 *   steering servo  pulse_us = 1000 + byte * 1000 / 255   (0 -> 1000 us, 255 -> 2000 us)
 *   ESC (throttle)  pulse_us = 1500 +/- byte * 500 / 255  (sign = direction; 0 -> 1500 us)
 *   H-bridge        duty = byte, direction line = sign (differential drive, per side)
 * Ackermann: steering table for the servo, speed table for the ESC.
 * Differential: the steering angle is turned into a yaw rate as if the robot
 * were an Ackermann car of wheelbase track_mm (omega = v tan(phi) / track), and
 * each side's speed goes through that side's speed table. Below spin_below_mm_s
 * (where an arc would need a speed inside the motors' dead band) the robot
 * turns on the spot instead: the wheels get -/+ steer / 45 deg * spin_mm_s, so a
 * positive (left) steer at standstill spins it counter-clockwise.
 */
#ifndef AGNAV_DRIVE_H
#define AGNAV_DRIVE_H

#include <stdbool.h>
#include <stdint.h>

#include "params.h"

struct calib_table_s; /* calib.h */

typedef enum { DRIVE_ACKERMANN = 0, DRIVE_DIFFERENTIAL = 1 } drive_kind_t;

typedef struct {
    uint8_t kind;             /* drive_kind_t */
    uint16_t track_mm;        /* differential: wheel separation; 0 = 191 */
    uint16_t spin_mm_s;       /* differential: wheel speed of a full (45 deg) spin command; 0 = 300 */
    uint16_t spin_below_mm_s; /* differential: |speed| below which steering spins on the spot; 0 = 100 */
} drive_cfg_t;

/* What went to the actuators last (for telemetry and tests). */
typedef struct {
    uint16_t steer_us;    /* Ackermann servo pulse */
    uint16_t throttle_us; /* Ackermann ESC pulse */
    int16_t left_mm_s;    /* differential: per-side speeds asked of the tables */
    int16_t right_mm_s;
    uint8_t left_duty;
    uint8_t right_duty;
    int8_t direction;     /* sign of the commanded speed, for Hall encoder hints */
} drive_output_t;

/* The parameters (drive_params.c: DRIVE_KIND, TRACK_MM; the robot's build, taken at boot). */
extern drive_cfg_t drive_params;
extern const PARAMS_ROM param_group_t DRIVE_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

void drive_init(const drive_cfg_t *cfg);
/* Physical command (positive steer = left, positive speed = forward). */
void drive_apply(int16_t steer_cdeg, int16_t speed_mm_s);
/* Calibration mode: table units straight to the outputs (speed byte signed by dir). */
void drive_apply_raw(uint16_t steer_pwm, uint16_t speed_pwm, int8_t dir);
/* What drive_apply_raw(steer_pwm, speed_pwm, dir) drives, as a physical command through the active
 * tables (forward lookup), so that the speed and steering limits apply to raw outputs too: Ackermann
 * the steering and speed tables; differential no turn (both sides get the one duty) and the faster
 * side's speed. A speed byte inside the dead band reads as 1 mm/s in its direction (still motion
 * for the avoid layer, which must see a start towards an obstacle before the wheels do); 0 is 0. */
void drive_raw_physical(uint16_t steer_pwm, uint16_t speed_pwm, int8_t dir, int16_t *steer_cdeg, int16_t *speed_mm_s);
/* Neutral outputs: centred steering, zero throttle / duty. */
void drive_stop(void);
const drive_output_t *drive_output(void);

/* Whether this output stage can drive table ``id`` (calib.h ids) as given: its pwm column is the 0..255
 * command byte (the calibration module accepts 0..3000 for other stages: a table in servo microseconds
 * would saturate to full throttle / full lock here), and a speed table is sign-magnitude (neutral 0: the
 * direction comes from the sign, so a non-zero neutral would be a creep at "stop"). */
bool drive_table_fits(uint8_t id, const struct calib_table_s *t);

uint16_t drive_servo_us_from_byte(uint16_t byte);
uint16_t drive_esc_us_from_byte(uint16_t byte, int8_t dir);

#endif
