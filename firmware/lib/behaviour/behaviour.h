/*
 * Behaviour layers and subsumption arbitration, run at 50 Hz.
 *
 * Every tick each layer looks at the same input snapshot and either proposes
 * a drive command or abstains; the highest-priority proposal wins:
 *
 *   FAILSAFE > AVOID_OBSTACLE > MANUAL > FOLLOW_WALL > HOST_COMMAND > MOVE_TO_GOAL
 *   (nobody proposes -> IDLE: stop, reason NO_COMMAND)
 *
 * Layers are evaluated bottom-up because AVOID_OBSTACLE needs to know whether
 * the best lower proposal drives forward (passive motion safety only acts on
 * forward motion). Pure logic: no HAL calls, time comes from the input.
 *
 * One limiter after every source: MAX_SPEED_MM_S / MAX_STEER_CDEG clamp the winning
 * proposal, whichever layer made it (host physical or raw PWM setpoints, whose outputs
 * the control task maps back through the calibration tables; manual override; the firmware's own
 * goal, wall and avoid layers).
 *
 * Failsafe hold: after any stop failsafe (e-stop, link loss, sensor fault, watchdog
 * boot; a boot starts held too) the robot moves again only on a fresh command. Every
 * command layer is held until the stop is over and a command of its own kind has been
 * taken since the stop began: the host layer a new setpoint (with a sequence number newer
 * than the last one before the stop, so a replayed setpoint is not one, unless an
 * arm came since: a new host session starts its numbers again), the manual layer a new
 * override, move-to-goal a new goal (a goal stored before the failsafe is never used
 * again); follow-wall (which needs no command) any of these, a SET_BEHAVIOURS, or an
 * arm. Heartbeats keep the link alive but release nothing. While nothing is released
 * the avoid layer does not start its back-off either: the robot stays where it stopped.
 *
 * Conventions: REP-103 body frame, x forward, y left; angles CCW positive, so
 * a positive steer_cdeg turns left; speed_mm_s negative = reverse.
 * Units: _mm, _mm_s, _cdeg (1/100 deg), _ms.
 */
#ifndef AGNAV_BEHAVIOUR_H
#define AGNAV_BEHAVIOUR_H

#include <stdbool.h>
#include <stdint.h>

#include "params.h"
#include "sonar_ring.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Active layer. Numeric values are mirrored by the MAVLink protocol enum. */
typedef enum {
    BHV_LAYER_IDLE = 0,           /* no layer commands: stop */
    BHV_LAYER_FAILSAFE = 1,
    BHV_LAYER_AVOID_OBSTACLE = 2,
    BHV_LAYER_MANUAL = 3,
    BHV_LAYER_FOLLOW_WALL = 4,
    BHV_LAYER_HOST_COMMAND = 5,
    BHV_LAYER_MOVE_TO_GOAL = 6
} bhv_layer_t;

/* Failsafe / health flag bits (out.failsafe_flags). */
#define BHV_FS_ESTOP 1u            /* e-stop latched (input active, or not yet cleared by behaviour_arm) */
#define BHV_FS_LINK_LOSS 2u        /* no host heartbeat/command/manual message within link_timeout_ms */
#define BHV_FS_ENCODER_FAULT 4u    /* encoder fault input */
#define BHV_FS_SONAR_FAULT 8u      /* sonar fault input */
#define BHV_FS_WATCHDOG_RESET 16u  /* booted from a watchdog reset, not yet cleared by behaviour_arm */
#define BHV_FS_CALIB_DEFAULTED 32u /* calibration fell back to defaults: health only, does not stop */
#define BHV_FS_STOP_MASK (BHV_FS_ESTOP | BHV_FS_LINK_LOSS | BHV_FS_ENCODER_FAULT | BHV_FS_SONAR_FAULT | BHV_FS_WATCHDOG_RESET)

/* Why the output is what it is. Values mirrored by the protocol enum. */
typedef enum {
    BHV_REASON_NONE = 0,             /* not used in outputs; placeholder */
    BHV_REASON_ESTOP = 1,            /* failsafe: e-stop latched, stopped until cleared */
    BHV_REASON_LINK_LOSS = 2,        /* failsafe: host link silent longer than link_timeout_ms */
    BHV_REASON_SENSOR_FAULT = 3,     /* failsafe: encoder or sonar fault reported */
    BHV_REASON_WATCHDOG_BOOT = 4,    /* failsafe: watchdog reset, waiting for behaviour_arm() */
    BHV_REASON_OBSTACLE_STOP = 5,    /* avoid: obstacle in the front cone, stopping */
    BHV_REASON_OBSTACLE_BACKOFF = 6, /* avoid: reversing avoid_backoff_mm */
    BHV_REASON_OBSTACLE_WAIT = 7,    /* avoid: standing still avoid_wait_ms for the path to clear */
    BHV_REASON_MANUAL_OVERRIDE = 8,  /* manual: fresh RC override / manual control */
    BHV_REASON_WALL_LEFT = 9,        /* follow wall: nearer obstacles on the left (steering away / along it) */
    BHV_REASON_WALL_RIGHT = 10,      /* follow wall: nearer obstacles on the right */
    BHV_REASON_CANYON_TIMER = 11,    /* follow wall: a canyon timer held the turn direction */
    BHV_REASON_HOST_SETPOINT = 12,   /* host command: fresh host setpoint passed through (limited) */
    BHV_REASON_GOAL_SEEK = 13,       /* move to goal: steering toward the goal */
    BHV_REASON_GOAL_REACHED = 14,    /* move to goal: within goal_tol_mm, stopped */
    BHV_REASON_NO_COMMAND = 15       /* idle: no layer proposed anything, stopped */
} bhv_reason_t;

/* Mode flags (in.mode_flags); same bits as link's LINK_ENABLE_*. */
#define BHV_MODE_FOLLOW_WALL 1u
#define BHV_MODE_GOAL_SEEK 2u
#define BHV_MODE_AVOID 4u /* passive motion safety on (link's default); off only for tests/bench work */

/* Tunables: the PARAM_* rows, ranges and defaults in behaviour_params.c. */
typedef struct {
    /* general */
    uint16_t link_timeout_ms;        /* link lost when the newest heartbeat/setpoint/manual is older */
    uint16_t host_timeout_ms;        /* host setpoint older than this is ignored */
    uint16_t manual_timeout_ms;      /* manual override older than this is ignored */
    int16_t max_speed_mm_s;          /* |speed| limit applied to every layer */
    int16_t max_steer_cdeg;          /* |steer| limit applied to every layer */
    /* avoid obstacle (passive motion safety, ref 001) */
    uint16_t avoid_stop_mm;          /* obstacle closer than this in the front cone stops the robot */
    int16_t avoid_cone_cdeg;         /* front cone half angle (S11, S0, S1 on the 12-ring) */
    int16_t avoid_moving_mm_s;       /* measured speed above which the robot counts as moving forward */
    uint16_t avoid_stop_ms;          /* minimum standstill before backing off */
    uint16_t avoid_backoff_mm;       /* reverse distance (odometry: integrated measured speed) */
    int16_t avoid_backoff_speed_mm_s;/* reverse speed (magnitude) */
    uint16_t avoid_rear_clear_mm;    /* back-off ends early if the rear cone sees closer than this */
    uint16_t avoid_wait_ms;          /* standstill after backing off, then release */
    /* follow wall (ref 002) */
    uint16_t wall_r0_mm;             /* margin R0 added to every range (keeps 1/R finite) */
    int16_t wall_speed_mm_s;         /* vmax of the layer */
    uint16_t wall_dt_ms;             /* sampling period dt (one sonar ring pass) */
    uint8_t wall_imax_steps;         /* Imax horizon in steps of vmax*dt: stop closer */
    uint8_t wall_imin_steps;         /* Imin horizon in steps of vmax*dt: ignore farther */
    uint16_t wall_deadband;          /* |l - r| below this (1/km) is "balanced": no correction */
    uint8_t wall_gain_q4;            /* proportional steer, cdeg per (1/km) of l - r, Q4 (32 = 2.0) */
    int16_t wall_turn_steer_cdeg;    /* steer used when the front is blocked (turn-away choice) */
    int8_t wall_tie_dir;             /* blocked and l == r: -1 turns right, +1 left */
    uint16_t wall_canyon_ms;         /* canyon timer T; 0 disables the timers */
    /* move to goal */
    int16_t goal_speed_mm_s;         /* cruise speed */
    int16_t goal_min_speed_mm_s;     /* crawl speed near the goal or while turning toward it */
    uint16_t goal_slow_mm;           /* slow down linearly inside this distance */
    uint16_t goal_tol_mm;            /* GOAL_REACHED inside this distance */
} behaviour_params_t;

/* The parameter variables (behaviour_params.c): PARAM_SET changes them, the layers take them
 * with behaviour_set_params(). behaviour_boot_modes: the BHV_MODE_* enabled at boot (BHV_MODES). */
extern behaviour_params_t behaviour_params;
extern uint8_t behaviour_boot_modes;
extern const PARAMS_ROM param_group_t BEHAVIOUR_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

/* Everything the layers look at, filled once per tick by the modules that own the fields
 * (link_behaviour_inputs, odom_behaviour_inputs, the sonar frame task) and the control task
 * (lib/control: faults, time).
 * A *_valid flag false means "never received". Times are hal_time_ms() values. */
typedef struct behaviour_in_s {
    uint32_t now_ms;
    sonar_frame_t sonar;            /* latest complete ring (sonar_ring_snapshot) */
    /* host link */
    int16_t host_steer_cdeg;        /* host drive setpoint */
    int16_t host_speed_mm_s;
    uint32_t host_rx_ms;            /* when that setpoint arrived */
    bool host_valid;
    uint16_t host_seq;              /* its sequence number (the host counts up, wrapping) */
    uint8_t host_gen;               /* setpoints taken so far (wraps): a change is a new setpoint */
    uint32_t heartbeat_rx_ms;       /* newest host heartbeat */
    bool heartbeat_valid;
    /* manual override (RC_CHANNELS_OVERRIDE / MANUAL_CONTROL, decoded by link) */
    int16_t manual_steer_cdeg;
    int16_t manual_speed_mm_s;
    uint32_t manual_rx_ms;
    bool manual_valid;
    uint8_t manual_gen;             /* manual messages taken (wraps) */
    /* safety inputs */
    bool estop;                     /* e-stop input active */
    bool encoder_fault;
    bool sonar_fault;
    bool reset_was_watchdog;        /* latched on its rising edge (pass the boot reset cause) */
    bool calib_defaulted;           /* health only */
    /* state estimate */
    int32_t x_mm;                   /* odometry pose, world frame */
    int32_t y_mm;
    int16_t heading_cdeg;           /* CCW from world x */
    int16_t speed_mm_s;             /* measured forward speed, signed */
    /* goal */
    int32_t goal_x_mm;
    int32_t goal_y_mm;
    bool goal_active;
    uint8_t goal_gen;               /* goals taken (wraps) */
    uint8_t mode_flags;             /* BHV_MODE_* */
    uint8_t mode_gen;               /* SET_BEHAVIOURS commands taken (wraps) */
} behaviour_in_t;

typedef struct {
    int16_t steer_cdeg;             /* positive = left */
    int16_t speed_mm_s;             /* negative = reverse */
    uint8_t layer;                  /* bhv_layer_t */
    uint8_t reason;                 /* bhv_reason_t */
    uint8_t failsafe_flags;         /* BHV_FS_* */
} behaviour_out_t;

/* Reset all layer state; params are copied (main: &behaviour_params). ring gives the
 * sensor bearings (kept by pointer); NULL = no sonar (avoid and follow-wall
 * abstain). Per-sensor cos/sin are precomputed here from integer tables. */
void behaviour_init(const behaviour_params_t *params, const sonar_ring_cfg_t *ring);

/* New parameter values (PARAM_SET at run time): the layers use them from the next tick; what is
 * derived from them (sensor classes, wall-follow thresholds) is recomputed, while the state (latches,
 * timers, the active layer) is kept. */
void behaviour_set_params(const behaviour_params_t *params);

/* One 50 Hz tick: evaluate the layers on *in, arbitrate, write *out. */
void behaviour_step(const behaviour_in_t *in, behaviour_out_t *out);

/* Optional, once per new ring frame (lib/control's sonar-frame task): work out the follow-wall sums of
 * the frame ahead of time, so the control tick does no per-sensor division. behaviour_step()
 * uses them while in->sonar.seq is that frame's seq and computes them itself otherwise; the
 * result is the same either way. The frame must not change afterwards without a new seq. */
void behaviour_sonar_frame(const sonar_frame_t *frame);

/* Host "arm"/clear: drops the e-stop latch (re-latches next tick if the
 * e-stop input is still active) and the watchdog-boot latch, releases the
 * follow-wall hold and starts a new host session (the next new setpoint counts
 * whatever its sequence number). It does not release a stored goal or setpoint. */
void behaviour_arm(void);

/* Last follow-wall obstacle extents l and r in 1/km (0 when no sonar). */
void behaviour_wall_extents(uint32_t *l_per_km, uint32_t *r_per_km);

/* Integer trigonometry (shared with tests and telemetry):
 * cos/sin of an angle in cdeg (any value, wrapped), Q14 (16384 = 1.0),
 * 5-degree table with linear interpolation, |error| < 0.001. */
int16_t behaviour_cos_q14(int32_t angle_cdeg);
int16_t behaviour_sin_q14(int32_t angle_cdeg);
/* atan2(y, x) in cdeg, -18000..18000, |error| < 0.05 deg; (0,0) -> 0. */
int16_t behaviour_atan2_cdeg(int32_t y, int32_t x);
/* Wrap to -18000..17999. */
int32_t behaviour_wrap_cdeg(int32_t angle_cdeg);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_BEHAVIOUR_H */
