/*
 * The wheels in the control tick: each encoder's travel since the last tick, checked for
 * plausibility, into the odometry of the robot's drive layout, and the encoders' health check.
 * Called by the control task (lib/control), once per tick, update first:
 *
 *   wheels_update_odometry()  encoder_update(), then the travel of each wheel: beyond
 *                             WHEELS_MAX_TICK_UM (10 m/s at 20 ms) it is no wheel of an AgNav robot
 *                             but a noisy or shorted line, clamped before odometry (whose work
 *                             grows with the distance: a 20 kHz storm of Hall pulses took 1.9 M
 *                             cycles, 121 ms, per tick on the AVR and the watchdog reset the board)
 *                             and reported as an encoder error. Differential drive: left = wheel 0
 *                             (and 2), right = wheel 1 (and 3); Ackermann: the rear wheels' mean
 *                             and the steering angle the last tick commanded.
 *   wheels_check_health()     health_encoders() with "driving" = a command that is not raw PWM,
 *                             not zero, and outputs that are not neutral.
 */
#ifndef AGNAV_WHEELS_H
#define AGNAV_WHEELS_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define WHEELS_MAX_TICK_UM 200000L /* travel of one wheel in one control tick above this: implausible */

/* One control tick's travel into odometry. steer_cdeg: the steering angle the last tick commanded
 * (Ackermann). count_lo / edges_lo (ENCODER_MAX entries): the low 16 bits of each wheel's count and
 * edge total as this update folded them, for wheels_check_health() (no second fold per tick). */
void wheels_update_odometry(int16_t steer_cdeg, uint16_t *count_lo, uint16_t *edges_lo);

/* Encoder health, before this tick's command. commanded: the last tick drove a physical command
 * (not raw PWM: the calibration sweep drives below the motion threshold on purpose) other than
 * zero; the drive's outputs tell whether it moved them off neutral (the calibration dead band
 * already maps too-slow requests to neutral). */
void wheels_check_health(uint32_t now_ms, bool commanded, const uint16_t *count_lo, const uint16_t *edges_lo);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_WHEELS_H */
