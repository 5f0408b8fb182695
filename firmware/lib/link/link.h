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
 */
#ifndef AGNAV_LINK_H
#define AGNAV_LINK_H

#include <stdbool.h>
#include <stdint.h>

#include <agnav_mavlink.h>

typedef struct {
    int16_t steer_cdeg;  /* positive left */
    int16_t speed_mm_s;  /* positive forward */
    uint16_t steer_pwm;  /* raw outputs in AGNAV_DRIVE_RAW_PWM mode */
    uint16_t speed_pwm;
    uint8_t mode;        /* AGNAV_DRIVE_MODE */
    uint16_t seq;
    uint32_t rx_ms;      /* when it arrived */
    bool valid;
} link_setpoint_t;

typedef struct {
    int16_t steer_cdeg;
    int16_t speed_mm_s;
    uint32_t rx_ms;
    bool valid;
} link_manual_t;

typedef struct {
    int32_t x_mm; /* odometry frame, REP-103 */
    int32_t y_mm;
    bool active;
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
    uint16_t rx_frames;
    uint16_t rx_errors;  /* frames of known messages with a bad CRC */
    uint16_t rx_unknown; /* frames of messages the firmware does not parse (skipped) */
    uint16_t tx_drops;   /* frames dropped because the UART queue was full */
} link_state_t;

typedef struct {
    uint8_t sysid;
    uint8_t compid;
    int16_t manual_max_steer_cdeg; /* full stick deflection */
    int16_t manual_max_speed_mm_s;
    /* Called from link_poll() with each AGNAV_CALIB_TABLE / AGNAV_CALIB_REQUEST addressed
     * to this robot (decoded there, so the link keeps no copy: RAM is scarce). May be NULL. */
    void (*on_calib)(const mavlink_message_t *msg);
} link_cfg_t;

void link_init(const link_cfg_t *cfg);
/* Read and handle everything received so far. now_ms stamps what arrives. */
void link_poll(uint32_t now_ms);
link_state_t *link_state(void);
/* Serialise msg (already packed with link_sysid/compid) to the UART; false when dropped. */
bool link_send(const mavlink_message_t *msg);
uint8_t link_sysid(void);
uint8_t link_compid(void);
void link_send_statustext(uint8_t severity, const char *text);
/* Hand one received byte stream chunk to the parser (used by link_poll and by tests). */
void link_feed(const uint8_t *data, uint16_t len, uint32_t now_ms);

/* Map a 1000..2000 us RC channel to -full..+full around 1500 (a +-20 us dead zone);
 * 0 and UINT16_MAX mean "released". Exposed for tests. */
int16_t link_rc_to_range(uint16_t pulse_us, int16_t full);

#endif
