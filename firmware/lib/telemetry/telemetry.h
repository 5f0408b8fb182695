/*
 * What the robot reports on its own over the link (docs/protocol.md has the rates):
 *
 *   telemetry_task_50hz()      every control tick, right after the control task: AGNAV_BEHAVIOUR_STATUS
 *                              in the tick the layer, reason or a failsafe flag changes, else every
 *                              TELEMETRY_STATUS_KEEPALIVE_MS (all 50 per second would take 1.2 kB/s
 *                              of the ~1.5 kB/s a 57600-baud radio has for telemetry).
 *   telemetry_task()           the 10 Hz and 1 Hz messages, one frame per 20 ms call in a fixed
 *                              rotation of five slots per 100 ms cycle (docs/safety.md "Signing":
 *                              with SIGN_TELEM each signed frame costs ~5.7 ms of SHA-256 on the AVR;
 *                              one per tick, after the control tick and BEHAVIOUR_STATUS, leaves the
 *                              rest of the 20 ms period to the link task's verification):
 *                                slot 0: the 1 Hz messages, one per 200 ms (cycles 0, 2, 4, 6 of each
 *                                        second: HEARTBEAT, SYS_STATUS, NAMED_VALUE_INT "HEALTH",
 *                                        NAMED_VALUE_INT "T_<task>"); cycle 9: storage upkeep at rest
 *                                slot 1: AGNAV_ODOMETRY (10 Hz)
 *                                slot 2: AGNAV_ENCODER_STATUS (2 Hz, cycles 4, 9) or
 *                                        LOCAL_POSITION_NED (2 Hz, cycles 1, 6)
 *                                slot 3: AGNAV_SONAR_RING (10 Hz, when fitted)
 *                                slot 4: nothing
 *                              A call that finds a received frame waiting leaves its slot to the link
 *                              (the same slot next tick, never two ticks in a row).
 *   telemetry_report_health()  from the control tick: one STATUSTEXT per newly latched health bit, at
 *                              most one per tick (twelve sonars failing together would otherwise send
 *                              twelve frames in one tick).
 *   telemetry_report_boot()    once at boot (docs/safety.md "Controller faults"): the reset cause, a
 *                              clock without crystal, and which stored records are not in use.
 * The values come from lib/control (behaviour output, sonar frame), the odometry, the encoders, the
 * health monitor, the link's counters and the scheduler's task statistics.
 */
#ifndef AGNAV_TELEMETRY_H
#define AGNAV_TELEMETRY_H

#include "hal.h"
#include "params.h"

#ifdef __cplusplus
extern "C" {
#endif

#define TELEMETRY_STATUS_KEEPALIVE_MS 200u

/* A fresh start: rotation at slot 0 of cycle 0, the 1 Hz messages from HEARTBEAT, the task report
 * from the scheduler's first row, no BEHAVIOUR_STATUS sent yet. */
void telemetry_reset(void);

void telemetry_task_50hz(void);
void telemetry_task(void);

void telemetry_report_health(void);

/* cause: this boot's reset cause; params_rc: what params_load() found. */
void telemetry_report_boot(hal_reset_cause_t cause, params_result_t params_rc);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_TELEMETRY_H */
