/*
 * Dead-reckoning odometry for the two drive layouts AgNav supports:
 *   differential  left/right wheel travel, track width
 *   Ackermann     rear-axle travel + steering angle of the virtual middle
 *                 front wheel (bicycle model, as ref 003 assumes), wheelbase
 *
 * Frame and signs (REP-103): x forward / y left in the odometry frame,
 * heading counter-clockwise positive from +x, positive steering = turn left,
 * positive yaw rate = turning left. The pose reference point is the middle
 * of the driven axle (between the two wheels for differential drive, the
 * rear-axle centre for Ackermann).
 *
 * Integration (per call): heading change dth, travel ds along the heading at
 * the middle of the step (second-order / midpoint rule). For a constant-
 * curvature step the midpoint rule uses the arc length instead of the chord,
 * a relative position error of dth^2/24 per step (4e-6 for 0.01 rad).
 * Large steps are cut into pieces of at most 32 mm first.
 *
 * Arithmetic: integer only. Heading is kept as a 32-bit binary angle
 * (2^32 = one turn, 1.5e-9 rad resolution; wraps by itself). Position is
 * int32 mm plus a 0..999 um remainder, so steps smaller than 1 mm are never
 * lost. sin/cos come from a 65-entry quarter-wave Q15 table with linear
 * interpolation: max error 1e-4 (~0.1 mm per metre of travel);
 * tan(steer) from a 0.5-degree Q24 table: relative error < 2.5e-5 from 1
 * to 20 degrees (curvature needs relative accuracy), < 4e-5 up to 45.
 * Per call: no division, no float; the differential update uses only
 * 32-bit multiplies, the Ackermann update two 64-bit ones (curvature and
 * yaw-rate gain, once per call). Measured on the ATmega2560 (-Os): see
 * docs/firmware/encoder_odometry_calib.md.
 */
#ifndef AGNAV_ODOMETRY_H
#define AGNAV_ODOMETRY_H

#include <stdbool.h>
#include <stdint.h>

#include "params.h"

#ifdef __cplusplus
extern "C" {
#endif

#define ODOM_DEFAULT_WHEELBASE_MM 174u /* ref 003 RC car, front to rear axle */
#define ODOM_DEFAULT_TRACK_MM 191u     /* ref 003 RC car width; set the real track */
#define ODOM_STEER_LIMIT_CDEG 4500     /* steering is clamped to +-45 degrees */

typedef enum {
    ODOM_MODEL_DIFF = 0,
    ODOM_MODEL_ACKERMANN = 1
} odom_model_t;

typedef struct {
    uint8_t model;         /* odom_model_t (informational: the caller picks the update function) */
    uint16_t track_mm;     /* differential: distance between the wheel contact lines, 0 = default */
    uint16_t wheelbase_mm; /* Ackermann: rear axle to front axle, 0 = default 174 */
} odom_cfg_t;

typedef struct {
    int32_t x_mm;            /* position of the reference point */
    int32_t y_mm;
    int32_t heading_cdeg;    /* (-18000, 18000], CCW positive from +x */
    int32_t speed_mm_s;      /* forward speed of the reference point */
    int32_t yaw_rate_cdeg_s; /* CCW positive */
} odom_pose_t;

/* The parameter (odometry_params.c: WHEELBASE_MM, taken at boot). */
extern uint16_t odom_param_wheelbase_mm;
extern const PARAMS_ROM param_group_t ODOMETRY_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

/* Reset to pose (0, 0, 0) with zero speeds. Zero cfg fields take the
 * defaults; cfg may be NULL for all defaults. Returns false if the model is
 * unknown (defaults are used). */
bool odom_init(const odom_cfg_t *cfg);

/* Overwrite the pose (e.g. after a GPS fix or at a known start). The
 * sub-millimetre remainders are cleared. heading_cdeg may be any value; it is
 * wrapped. */
void odom_set_pose(int32_t x_mm, int32_t y_mm, int32_t heading_cdeg);

/* Differential drive step: wheel travel since the last call in um (forward
 * positive, from encoder_update()), and the wheel speeds in mm/s for the
 * reported speed and yaw rate. */
void odom_update_diff(int32_t left_um, int32_t right_um, int32_t left_mm_s, int32_t right_mm_s);

/* Ackermann step: rear-axle-centre travel in um (mean of the rear wheels, or
 * the single encoded wheel), steering angle of the virtual middle front wheel
 * in cdeg (positive left, clamped to +-ODOM_STEER_LIMIT_CDEG) and rear speed
 * in mm/s. Curvature = tan(steer) / wheelbase. */
void odom_update_ackermann(int32_t rear_um, int32_t steer_cdeg, int32_t rear_mm_s);

/* Current pose and speeds. */
void odom_get(odom_pose_t *out);

/* The pose into the behaviour inputs (x_mm, y_mm, heading_cdeg, speed_mm_s), every control tick. */
struct behaviour_in_s;
void odom_behaviour_inputs(struct behaviour_in_s *in);

/* Heading as a binary angle, 2^32 per turn (finer than cdeg). */
uint32_t odom_heading_bam(void);

/* Table helpers, exposed for tests and other modules.
 * Angle as a binary angle (2^32 per turn); result Q15 (32768 = 1.0). */
int32_t odom_sin_q15(uint32_t angle_bam);
int32_t odom_cos_q15(uint32_t angle_bam);
/* tan of a steering angle in cdeg, clamped to +-45 degrees; Q24
 * (16777216 = 1.0). */
int32_t odom_tan_q24(int32_t angle_cdeg);
/* Binary angle from cdeg (any value) and back to (-18000, 18000]. */
uint32_t odom_bam_from_cdeg(int32_t angle_cdeg);
int32_t odom_cdeg_from_bam(uint32_t angle_bam);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_ODOMETRY_H */
