#include "link.h"

#include <string.h>

#include "hal.h"
#include "params.h"

#define RC_DEADZONE_US 20
#define PARAM_SEND_PER_POLL 2u /* paced so a PARAM list does not flood a 57600 link */

static link_cfg_t s_cfg;
static link_state_t s_state;
static mavlink_message_t s_rx_msg;
static mavlink_status_t s_rx_status;
static uint16_t s_param_next = 0xFFFFu; /* next index of a running PARAM_REQUEST_LIST */

void link_init(const link_cfg_t *cfg)
{
    s_cfg = *cfg;
    memset(&s_state, 0, sizeof s_state);
    memset(&s_rx_status, 0, sizeof s_rx_status);
    s_state.behaviour_enable = LINK_ENABLE_AVOID;
    s_param_next = 0xFFFFu;
}

link_state_t *link_state(void) { return &s_state; }
uint8_t link_sysid(void) { return s_cfg.sysid; }
uint8_t link_compid(void) { return s_cfg.compid; }

bool link_send(const mavlink_message_t *msg)
{
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    uint16_t len = mavlink_msg_to_send_buffer(buf, msg);
    if (hal_uart_tx_space(HAL_UART_LINK) < len) {
        s_state.tx_drops++;
        return false;
    }
    hal_uart_write(HAL_UART_LINK, buf, len);
    return true;
}

void link_send_statustext(uint8_t severity, const char *text)
{
    mavlink_message_t msg;
    char t[50];
    memset(t, 0, sizeof t);
    strncpy(t, text, sizeof t);
    mavlink_msg_statustext_pack(s_cfg.sysid, s_cfg.compid, &msg, severity, t, 0, 0);
    (void)link_send(&msg);
}

static void send_command_ack(uint16_t command, uint8_t result, uint8_t to_sys, uint8_t to_comp)
{
    mavlink_message_t msg;
    mavlink_msg_command_ack_pack(s_cfg.sysid, s_cfg.compid, &msg, command, result, 0, 0, to_sys, to_comp);
    (void)link_send(&msg);
}

static void send_param(uint16_t index)
{
    param_def_t p;
    if (!params_def(index, &p)) {
        return;
    }
    mavlink_message_t msg;
    mavlink_msg_param_value_pack(s_cfg.sysid, s_cfg.compid, &msg, p.name, (float)params_get(index),
                                 MAV_PARAM_TYPE_INT32, params_count(), index);
    (void)link_send(&msg);
}

int16_t link_rc_to_range(uint16_t pulse_us, int16_t full)
{
    if (pulse_us == 0u || pulse_us == UINT16_MAX) {
        return 0;
    }
    int32_t d = (int32_t)pulse_us - 1500;
    if (d > -RC_DEADZONE_US && d < RC_DEADZONE_US) {
        return 0;
    }
    if (d > 500) {
        d = 500;
    } else if (d < -500) {
        d = -500;
    }
    return (int16_t)((d * full) / 500);
}

static bool for_us(uint8_t target_system, uint8_t target_component)
{
    return (target_system == 0u || target_system == s_cfg.sysid) &&
           (target_component == 0u || target_component == s_cfg.compid);
}

static void handle_command(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_command_long_t c;
    mavlink_msg_command_long_decode(m, &c);
    if (!for_us(c.target_system, c.target_component)) {
        return;
    }
    uint8_t result = MAV_RESULT_ACCEPTED;
    switch (c.command) {
    case MAV_CMD_AGNAV_ESTOP:
        s_state.estop = c.param1 > 0.5f;
        break;
    case MAV_CMD_COMPONENT_ARM_DISARM:
        if (c.param1 > 0.5f) {
            s_state.arm_request = true;
        } else {
            s_state.setpoint.valid = false;
            s_state.goal.active = false;
        }
        break;
    case MAV_CMD_AGNAV_SET_BEHAVIOURS:
        s_state.behaviour_enable = (uint8_t)((c.param1 > 0.5f ? LINK_ENABLE_FOLLOW_WALL : 0u) |
                                             (c.param2 > 0.5f ? LINK_ENABLE_GOAL_SEEK : 0u) |
                                             (c.param3 > 0.5f ? LINK_ENABLE_AVOID : 0u));
        break;
    case MAV_CMD_PREFLIGHT_STORAGE:
        /* param1: 0 read parameters back from EEPROM, 1 write them (boot-time ones such as
         * DRIVE_KIND take effect at the next boot). Other param1 values: unsupported. */
        if (c.param1 > 0.5f && c.param1 < 1.5f) {
            result = params_save(PARAMS_EEPROM_ADDR) == PARAMS_OK ? MAV_RESULT_ACCEPTED : MAV_RESULT_FAILED;
        } else if (c.param1 < 0.5f && c.param1 > -0.5f) {
            result = params_load(PARAMS_EEPROM_ADDR) == PARAMS_OK ? MAV_RESULT_ACCEPTED : MAV_RESULT_FAILED;
        } else {
            result = MAV_RESULT_UNSUPPORTED;
        }
        break;
    default:
        result = MAV_RESULT_UNSUPPORTED;
        break;
    }
    (void)now_ms;
    send_command_ack(c.command, result, m->sysid, m->compid);
}

static void handle_param_set(const mavlink_message_t *m)
{
    mavlink_param_set_t ps;
    mavlink_msg_param_set_decode(m, &ps);
    if (!for_us(ps.target_system, ps.target_component)) {
        return;
    }
    int16_t idx = params_find(ps.param_id);
    if (idx < 0) {
        link_send_statustext(MAV_SEVERITY_WARNING, "PARAM_SET: unknown parameter");
        return;
    }
    int32_t v = (int32_t)(ps.param_value >= 0.0f ? ps.param_value + 0.5f : ps.param_value - 0.5f);
    if (params_set((uint16_t)idx, v) != PARAMS_OK) {
        link_send_statustext(MAV_SEVERITY_WARNING, "PARAM_SET: value out of range, refused");
    }
    send_param((uint16_t)idx); /* the current value either way, as the protocol asks */
}

static void handle(const mavlink_message_t *m, uint32_t now_ms)
{
    s_state.rx_frames++;
    switch (m->msgid) {
    case MAVLINK_MSG_ID_HEARTBEAT:
        if (m->sysid != s_cfg.sysid) {
            s_state.host_heartbeat_ms = now_ms;
            s_state.host_seen = true;
        }
        break;
    case MAVLINK_MSG_ID_AGNAV_DRIVE_SETPOINT: {
        mavlink_agnav_drive_setpoint_t sp;
        mavlink_msg_agnav_drive_setpoint_decode(m, &sp);
        if (!for_us(sp.target_system, sp.target_component)) {
            break;
        }
        s_state.setpoint.steer_cdeg = sp.steer_cdeg;
        s_state.setpoint.speed_mm_s = sp.speed_mm_s;
        s_state.setpoint.steer_pwm = sp.steer_pwm;
        s_state.setpoint.speed_pwm = sp.speed_pwm;
        s_state.setpoint.mode = sp.mode;
        s_state.setpoint.seq = sp.seq;
        s_state.setpoint.rx_ms = now_ms;
        s_state.setpoint.valid = true;
        s_state.host_heartbeat_ms = now_ms;
        s_state.host_seen = true;
        break;
    }
    case MAVLINK_MSG_ID_RC_CHANNELS_OVERRIDE: {
        mavlink_rc_channels_override_t rc;
        mavlink_msg_rc_channels_override_decode(m, &rc);
        if (!for_us(rc.target_system, rc.target_component)) {
            break;
        }
        bool released = (rc.chan1_raw == 0u || rc.chan1_raw == UINT16_MAX) &&
                        (rc.chan3_raw == 0u || rc.chan3_raw == UINT16_MAX);
        /* Channel 1 is roll/steering (right stick right = turn right = negative), channel 3 throttle. */
        s_state.manual.steer_cdeg = (int16_t)-link_rc_to_range(rc.chan1_raw, s_cfg.manual_max_steer_cdeg);
        s_state.manual.speed_mm_s = link_rc_to_range(rc.chan3_raw, s_cfg.manual_max_speed_mm_s);
        s_state.manual.rx_ms = now_ms;
        s_state.manual.valid = !released;
        s_state.host_heartbeat_ms = now_ms;
        s_state.host_seen = true;
        break;
    }
    case MAVLINK_MSG_ID_MANUAL_CONTROL: {
        mavlink_manual_control_t mc;
        mavlink_msg_manual_control_decode(m, &mc);
        if (mc.target != 0u && mc.target != s_cfg.sysid) {
            break;
        }
        /* x: forward stick -1000..1000; r: yaw stick, positive = clockwise = right. */
        s_state.manual.speed_mm_s = (int16_t)(((int32_t)mc.x * s_cfg.manual_max_speed_mm_s) / 1000);
        s_state.manual.steer_cdeg = (int16_t)(-((int32_t)mc.r * s_cfg.manual_max_steer_cdeg) / 1000);
        s_state.manual.rx_ms = now_ms;
        s_state.manual.valid = true;
        s_state.host_heartbeat_ms = now_ms;
        s_state.host_seen = true;
        break;
    }
    case MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED: {
        mavlink_set_position_target_local_ned_t t;
        mavlink_msg_set_position_target_local_ned_decode(m, &t);
        if (!for_us(t.target_system, t.target_component)) {
            break;
        }
        s_state.goal.x_mm = (int32_t)(t.x * 1000.0f);
        s_state.goal.y_mm = (int32_t)(-t.y * 1000.0f);
        s_state.goal.active = true;
        break;
    }
    case MAVLINK_MSG_ID_COMMAND_LONG:
        handle_command(m, now_ms);
        break;
    case MAVLINK_MSG_ID_PARAM_REQUEST_LIST:
        s_param_next = 0u;
        break;
    case MAVLINK_MSG_ID_PARAM_REQUEST_READ: {
        mavlink_param_request_read_t r;
        mavlink_msg_param_request_read_decode(m, &r);
        int16_t idx = r.param_index >= 0 ? r.param_index : params_find(r.param_id);
        if (idx >= 0 && (uint16_t)idx < params_count()) {
            send_param((uint16_t)idx);
        }
        break;
    }
    case MAVLINK_MSG_ID_PARAM_SET:
        handle_param_set(m);
        break;
    case MAVLINK_MSG_ID_AGNAV_CALIB_TABLE:
        if (s_cfg.on_calib != 0 && for_us(mavlink_msg_agnav_calib_table_get_target_system(m),
                                          mavlink_msg_agnav_calib_table_get_target_component(m))) {
            s_cfg.on_calib(m);
        }
        break;
    case MAVLINK_MSG_ID_AGNAV_CALIB_REQUEST:
        if (s_cfg.on_calib != 0 && for_us(mavlink_msg_agnav_calib_request_get_target_system(m),
                                          mavlink_msg_agnav_calib_request_get_target_component(m))) {
            s_cfg.on_calib(m);
        }
        break;
    default:
        break;
    }
}

void link_feed(const uint8_t *data, uint16_t len, uint32_t now_ms)
{
    for (uint16_t i = 0; i < len; i++) {
        uint8_t r = mavlink_frame_char_buffer(&s_rx_msg, &s_rx_status, data[i], NULL, NULL);
        if (r == MAVLINK_FRAMING_OK) {
            handle(&s_rx_msg, now_ms);
        } else if (r == MAVLINK_FRAMING_BAD_CRC || r == MAVLINK_FRAMING_BAD_SIGNATURE) {
            if (mavlink_get_msg_entry(s_rx_msg.msgid) == NULL) {
                s_state.rx_unknown++; /* a message this firmware does not parse */
            } else {
                s_state.rx_errors++;
            }
        }
    }
}

void link_poll(uint32_t now_ms)
{
    uint8_t buf[32];
    uint16_t n;
    while ((n = hal_uart_read(HAL_UART_LINK, buf, sizeof buf)) > 0u) {
        link_feed(buf, n, now_ms);
    }
    for (uint8_t k = 0; k < PARAM_SEND_PER_POLL && s_param_next < params_count(); k++) {
        send_param(s_param_next++);
    }
    if (s_param_next >= params_count()) {
        s_param_next = 0xFFFFu;
    }
}
