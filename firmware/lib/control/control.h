/*
 * The robot's control loop: the scheduler's control task and the sonar ring's two tasks, and the
 * behaviour inputs and output they keep between ticks (read by lib/telemetry and lib/calib_service).
 *
 *   control_task()             50 Hz: wheels -> odometry and encoder health (lib/wheels), a
 *                              STATUSTEXT per newly latched health bit, the behaviour inputs (link,
 *                              odometry, faults, time), behaviour_step(), the drive outputs (a raw
 *                              PWM setpoint within the limits unchanged, else the limited physical
 *                              command through the calibration tables), the Hall direction hints.
 *   control_sonar_task()       every 1 ms: one step of the ring.
 *   control_sonar_frame_task() every 1 ms, after the control task in the table: a completed ring
 *                              frame into the behaviour inputs and the health monitor. In a pass
 *                              where a frame completes just as the control tick falls due, the tick
 *                              runs first and the frame's work (up to ~270 us on the AVR) after it.
 * A sonar fault is raised when no new ring came for CONTROL_SONAR_STALE_MS, when a fitted sensor of
 * the last frame answered nothing (missing, unplugged, stuck line: blind on that side), or when the
 * health monitor latched one; the behaviour failsafe then stops the robot (SONAR_COUNT = 0 for a
 * robot without sonars).
 */
#ifndef AGNAV_CONTROL_H
#define AGNAV_CONTROL_H

#include <stdbool.h>
#include <stdint.h>

#include "behaviour.h"
#include "sonar_ring.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CONTROL_SONAR_STALE_MS 500u /* no new ring for this long -> sonar fault */

/* A fresh start (on the board .bss is zeroed anyway; the native SIL re-enters the setup without
 * reloading the program): inputs, output and the last frame cleared, the frame clock starts at
 * hal_time_ms(). watchdog_boot: the reset was a watchdog or brown-out one (behaviour's latch). */
void control_reset(bool watchdog_boot);

/* ring: the fitted sonar ring (0: none; sonar_ring_init() done by the caller). params_corrupt: the
 * stored parameters were corrupt and defaults are in use (reported as calibration defaulted). */
void control_init(const sonar_ring_cfg_t *ring, bool params_corrupt);

void control_task(void);
void control_sonar_task(void);
void control_sonar_frame_task(void);

/* The last tick's behaviour output and its tick time (hal ms). */
const behaviour_out_t *control_out(void);
uint32_t control_out_ms(void);

/* The last complete ring frame (seq 0: none yet) and when it came (hal ms); 0 when no ring is fitted. */
const sonar_frame_t *control_sonar_frame(void);
uint32_t control_sonar_frame_ms(void);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_CONTROL_H */
