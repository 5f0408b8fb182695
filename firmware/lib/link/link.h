/*
 * Host link: MAVLink 2 over the telemetry UART (XBee or USB serial, 57600 baud).
 *
 * link_poll() drains the UART, parses frames and turns them into link_state_t
 * (setpoints, manual override, goal, e-stop, arm request, calibration writes),
 * answering PARAM_* and COMMAND_LONG itself. It never blocks: sends that do
 * not fit in the UART queue are dropped and counted (tx_drops), so telemetry
 * can never stall the control loop.
 *
 * Frames of REP-103 (x forward, y left, CCW positive) are used inside; NED
 * inputs (SET_POSITION_TARGET_LOCAL_NED) are converted here: y_left = -y_east.
 *
 * Input checks (docs/safety.md "Bad commands"): every message is checked for its target
 * (ours, or 0 = broadcast only for MAV_CMD_AGNAV_ESTOP, PARAM_REQUEST_* and HEARTBEAT; other
 * systems' messages are ignored and counted in rx_other_target; a component of this system other
 * than ours is refused), for NaN/inf in the floats it uses and for ranges. A refused COMMAND_LONG
 * is answered with COMMAND_ACK MAV_RESULT_DENIED (unknown ids: MAV_RESULT_UNSUPPORTED) and the
 * LINK_REFUSAL_* reason in result_param2; a refused calibration message with AGNAV_CALIB_ACK;
 * other messages get a STATUSTEXT reason (at most one per second). Every refusal is counted in
 * rx_refused. A refused motion message also drops the current one of its kind (the robot stops
 * rather than keep an older command).
 * Clamps (not refusals): steering and speed within the representable range are limited by
 * MAX_STEER_CDEG / MAX_SPEED_MM_S in the behaviour layer; RC pulses 800..1000 and 2000..2200 us
 * count as full deflection.
 *
 * Signing (firmware/lib/signing): with a key set, unsigned, wrongly signed and replayed frames
 * are dropped before dispatch and counted. SETUP_SIGNING sets or (all-zero key) clears the key
 * when it arrives signed with the current key, or in the provisioning window.
 */
#ifndef AGNAV_LINK_H
#define AGNAV_LINK_H

#include <stdbool.h>
#include <stdint.h>

#include "mavlink_lib.h"
#include "params.h"
#include "units.h"

typedef struct {
    int16_t steer_cdeg;  /* positive left */
    int16_t speed_mm_s;  /* positive forward */
    uint16_t steer_pwm;  /* raw outputs in AGNAV_DRIVE_RAW_PWM mode */
    uint16_t speed_pwm;
    uint8_t mode;        /* AGNAV_DRIVE_MODE */
    uint16_t seq;
    uint32_t rx_ms;      /* when it arrived */
    bool valid;
    uint8_t gen;         /* setpoints taken (wraps): a change is a new one (behaviour's failsafe hold) */
} link_setpoint_t;

typedef struct {
    int16_t steer_cdeg;
    int16_t speed_mm_s;
    uint32_t rx_ms;
    bool valid;
    uint8_t gen;  /* RC_CHANNELS_OVERRIDE / MANUAL_CONTROL messages taken (wraps) */
} link_manual_t;

typedef struct {
    int32_t x_mm; /* odometry frame, REP-103 */
    int32_t y_mm;
    bool active;
    uint8_t gen;  /* goals taken (wraps) */
} link_goal_t;

#define LINK_ENABLE_FOLLOW_WALL 0x01u
#define LINK_ENABLE_GOAL_SEEK 0x02u
#define LINK_ENABLE_AVOID 0x04u

typedef struct {
    link_setpoint_t setpoint;
    link_manual_t manual;
    link_goal_t goal;
    uint32_t host_heartbeat_ms; /* last HEARTBEAT or setpoint from the host */
    bool host_seen;
    bool estop;                 /* as last commanded (MAV_CMD_AGNAV_ESTOP) */
    bool arm_request;           /* one-shot: MAV_CMD_COMPONENT_ARM_DISARM(1) arrived */
    uint8_t behaviour_enable;   /* LINK_ENABLE_* */
    uint8_t behaviour_gen;      /* MAV_CMD_AGNAV_SET_BEHAVIOURS commands taken (wraps) */
    uint16_t rx_frames;
    uint16_t rx_errors;  /* frames of known messages with a bad CRC */
    uint16_t rx_unknown; /* frames of an id the dialect does not have (their CRC cannot be checked): dropped */
    uint16_t tx_drops;   /* frames dropped because the UART queue was full */
    /* Refusals (all saturate at 65535; sent in SYS_STATUS errors_count1..4, see docs/safety.md). */
    uint16_t rx_refused;       /* messages / commands for us refused: NaN/inf, out of range, broadcast
                                * motion, unsupported command or action, unauthorised key change, refused
                                * calibration writes, a component of this system other than ours */
    uint16_t rx_other_target;  /* addressed to another system: ignored */
    uint16_t rx_unsigned;      /* signing on: frames without a signature dropped */
    uint16_t rx_bad_signature; /* signing on: frames signed with another key dropped */
    uint16_t rx_replay;        /* signing on: frames with an old timestamp (replays) dropped */
    uint8_t storage_to_sys;    /* who asked for the parameter save in progress (its final COMMAND_ACK) */
    uint8_t storage_to_comp;
} link_state_t;

/* Why a command or message was refused: COMMAND_ACK.result_param2 (AGNAV_REFUSAL in agnav.xml). */
#define LINK_REFUSAL_NOT_FINITE ((uint8_t)AGNAV_REFUSAL_NOT_FINITE)     /* a used float is NaN or infinite */
#define LINK_REFUSAL_OUT_OF_RANGE ((uint8_t)AGNAV_REFUSAL_OUT_OF_RANGE) /* outside what the firmware allows */
#define LINK_REFUSAL_BROADCAST ((uint8_t)AGNAV_REFUSAL_BROADCAST)       /* sent to system 0: must be addressed */
#define LINK_REFUSAL_UNSIGNED ((uint8_t)AGNAV_REFUSAL_UNSIGNED)         /* key change not authorised */
#define LINK_REFUSAL_UNSUPPORTED ((uint8_t)AGNAV_REFUSAL_UNSUPPORTED)   /* unknown command id */

typedef struct {
    uint8_t sysid;
    uint8_t compid;
    int16_t manual_max_steer_cdeg; /* full stick deflection */
    int16_t manual_max_speed_mm_s;
    /* Called from link_poll() with each AGNAV_CALIB_TABLE / AGNAV_CALIB_REQUEST addressed
     * to this robot (decoded there, so the link keeps no copy: RAM is scarce); returns true when it
     * refused the message (the link counts it). May be NULL. */
    bool (*on_calib)(const mavlink_message_t *msg);
    /* Key provisioning window (ms after link_init) during which an UNSIGNED SETUP_SIGNING is
     * accepted: main opens it only after a power-on or external reset (the USB auto-reset of
     * the Mega, or the reset button), i.e. with someone at the robot. 0 = closed. */
    uint16_t provision_window_ms;
    /* hal_time_us() at which the 50 Hz control tick is next due (main: its scheduler row's
     * next_due_us). With a key, a received frame's SHA-256 (and, when SIGN_TELEM signs the
     * answers, the answer's) starts only when it ends before then (SIGNING_BLOCK_US per block
     * + SIGNING_MARGIN_US), else the frame waits in the UART queue for a later call
     * (docs/safety.md "Signing"). NULL = no limit. */
    const uint32_t *tick_due_us;
} link_cfg_t;

/* The parameter (link_params.c: SYSID_THISMAV, taken at boot). */
extern uint8_t link_param_sysid;
extern const PARAMS_ROM param_group_t LINK_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

void link_init(const link_cfg_t *cfg);

/* What the host asked for into the behaviour inputs (host setpoint, heartbeat, manual override,
 * e-stop, goal, enabled layers, the counts of each kind of command taken), every control tick. A raw
 * PWM setpoint's steer_cdeg / speed_mm_s go in as sent: the control task replaces them with what the raw outputs
 * amount to (drive_raw_physical), so that the layers and their limits see the real command. */
struct behaviour_in_s;
void link_behaviour_inputs(struct behaviour_in_s *in);

/* Full-stick steering and speed of manual control (MAX_STEER_CDEG / MAX_SPEED_MM_S changed at run time). */
void link_set_manual_limits(int16_t max_steer_cdeg, int16_t max_speed_mm_s);
/* A received signed frame has waited more than one call because its hash did not fit before the
 * control tick: telemetry_task() then skips its frame for a tick (never two ticks in a row) to
 * leave the link a longer window. */
bool link_rx_waiting(void);
/* Read and handle everything received so far. now_ms stamps what arrives. */
void link_poll(uint32_t now_ms);
link_state_t *link_state(void);
/* Serialise msg (already packed with link_sysid/compid) to the UART; false when dropped. */
bool link_send(const mavlink_message_t *msg);
uint8_t link_sysid(void);
uint8_t link_compid(void);
/* STATUSTEXT (up to 50 characters). The text lives in flash on the AVR: write
 * link_send_statustext(sev, LINK_TEXT("...")) so the literal never takes RAM. */
#if defined(__AVR__) && defined(__FLASH)
#define LINK_TEXT(s) (__extension__({ static const __flash char link_text_[] = (s); &link_text_[0]; }))
#else
#define LINK_TEXT(s) (s)
#endif
/* lib/storage finished records (storage_take_done()): the final COMMAND_ACK of a parameter save. */
void link_storage_done(uint8_t done, uint8_t failed);
void link_send_statustext(uint8_t severity, const UNITS_ROM char *text);
/* The same with the first '#' of text replaced by the decimal n (0..99): "sonar #: ...". */
void link_send_statustext_n(uint8_t severity, const UNITS_ROM char *text, uint8_t n);
/* Hand one received byte stream chunk to the parser (used by link_poll and by tests). */
void link_feed(const uint8_t *data, uint16_t len, uint32_t now_ms);

/* Map a 1000..2000 us RC channel to -full..+full around 1500 (pulses within 20 us of 1500 map to 0);
 * 0 and UINT16_MAX mean "released". Exposed for tests. */
int16_t link_rc_to_range(uint16_t pulse_us, int16_t full);

#endif
