#include "link.h"

#include <string.h>

#include "behaviour.h"
#include "hal.h"
#include "params.h"
#include "signing.h"
#include "storage.h"

#define RC_DEADZONE_US 20
#define RC_VALID_MIN_US 800u  /* pulses outside 800..2200 us are refused (1000..2000 nominal) */
#define RC_VALID_MAX_US 2200u
#define SETPOINT_STEER_LIMIT_CDEG 18000 /* beyond +-180 deg or +-10 m/s a setpoint is garbage */
#define SETPOINT_SPEED_LIMIT_MM_S 10000
#define RAW_PWM_LIMIT 3000u             /* CALIB_PWM_MAX */
#define REFUSAL_TEXT_GAP_MS 1000u
#define PARAM_SEND_PER_POLL 2u /* paced so a PARAM list does not flood a 57600 link */

static link_cfg_t s_cfg;
static link_state_t s_state;
static mavlink_message_t s_rx_msg;
static mavlink_status_t s_rx_status;
static uint16_t s_param_next = 0xFFFFu; /* next index of a running PARAM_REQUEST_LIST */
static uint32_t s_refusal_text_ms;
static bool s_refusal_text_sent;
static uint32_t s_provision_until_ms;
static uint8_t s_sha_waits; /* link_poll calls the frame in the parser has waited (LINK_SHA_MAX_WAITS) */

void link_init(const link_cfg_t *cfg)
{
    s_cfg = *cfg;
    memset(&s_state, 0, sizeof s_state);
    memset(&s_rx_status, 0, sizeof s_rx_status);
    s_state.behaviour_enable = LINK_ENABLE_AVOID;
    s_param_next = 0xFFFFu;
    s_refusal_text_sent = false;
    s_sha_waits = 0u; /* the native SIL re-enters link_init() without reloading the program */
    uint32_t now_ms = hal_time_ms();
    s_provision_until_ms = cfg->provision_window_ms != 0u ? now_ms + cfg->provision_window_ms : 0u;
    signing_init(&s_rx_status, mavlink_get_channel_status(MAVLINK_COMM_0), now_ms);
    signing_set_provisioning(cfg->provision_window_ms != 0u);
}

static void count(uint16_t *c)
{
    if (*c != UINT16_MAX) {
        (*c)++;
    }
}

/* The received floats are checked and converted on their IEEE-754 bits with integer operations
 * only: the AVR then links none of the float compare, add and float-to-integer routines. Each
 * test is exactly the float expression it stands for (every one of the 2^32 bit patterns was
 * compared on the host, and samples with all rounding ties on the AVR's float library). */
#define FB_MAG(b) ((b) & 0x7FFFFFFFul) /* |f|: the order of the bits is the order of the values */
#define FB_ONE 0x3F800000ul           /* 1.0f */
#define FB_3_4E38 0x7F7FC99Eul        /* 3.4e38f */
#define FB_2P24 0x4B800000ul          /* 16777216.0f */
#define FB_10000 0x461C4000ul         /* 10000.0f = GOAL_LIMIT_M */

static uint32_t fbits(float f)
{
    uint32_t b;
    memcpy(&b, &f, sizeof b);
    return b;
}

/* f == f && f <= 3.4e38f && f >= -3.4e38f: NaN and +-inf lie above 3.4e38f's bits */
static bool is_finite_f(float f) { return FB_MAG(fbits(f)) <= FB_3_4E38; }

/* f == 1.0f */
static bool is_one(float f) { return fbits(f) == FB_ONE; }

/* f == 0.0f (either zero) */
static bool is_zero(float f) { return (fbits(f) << 1) == 0u; }

/* q * 2^e rounded to float precision (24 bits, to nearest, ties to even), then truncated
 * towards zero: what a float operation whose exact result is q * 2^e, cast to an integer, gives. */
static uint32_t trunc_rne24(uint32_t q, int16_t e)
{
    bool half = false, sticky = false; /* the first bit shifted out; any bit after it */
    for (; q >= 0x1000000ul; e++) {
        sticky = sticky || half;
        half = (q & 1u) != 0u;
        q >>= 1;
    }
    if (half && (sticky || (q & 1u) != 0u)) {
        q++;
    }
    for (; e < 0 && q != 0u; e++) {
        q >>= 1;
    }
    for (; e > 0; e--) {
        q <<= 1;
    }
    return q;
}

static int32_t with_sign(uint32_t b, uint32_t v) { return (b & 0x80000000ul) != 0u ? -(int32_t)v : (int32_t)v; }

/* (int32_t)(f >= 0.0f ? f + 0.5f : f - 0.5f) for |f| < 2^24. |f| = m 2^(ex-150) and 0.5 =
 * 2^(150-ex) 2^(ex-151), so the exact sum is (2m + 2^(150-ex)) 2^(ex-151); below 0.25 it is 0. */
static int32_t round_half_away(float f)
{
    uint32_t b = fbits(f);
    uint8_t ex = (uint8_t)(b >> 23);
    uint32_t v = 0u;
    if (ex >= 125u) {
        uint32_t m = (b & 0x7FFFFFul) | 0x800000ul;
        v = trunc_rne24((m << 1) + (1ul << (150u - ex)), (int16_t)(ex - 151));
    }
    return with_sign(b, v);
}

/* (int32_t)(f * 1000.0f) for |f| <= 10000: with |f| = m 2^(ex-150) the exact product is
 * 125 m 2^(ex-147), 125 m < 2^31 (a subnormal f, read as a tiny normal one, gives 0 either way). */
static int32_t times_1000(float f)
{
    uint32_t b = fbits(f);
    uint8_t ex = (uint8_t)(b >> 23);
    uint32_t m = (b & 0x7FFFFFul) | 0x800000ul;
    return with_sign(b, trunc_rne24(m * 125u, (int16_t)(ex - 147)));
}

/* A refused non-command message: counted, one STATUSTEXT per REFUSAL_TEXT_GAP_MS at most. */
static void refuse(const UNITS_ROM char *why, uint32_t now_ms)
{
    count(&s_state.rx_refused);
    if (s_refusal_text_sent && (uint32_t)(now_ms - s_refusal_text_ms) < REFUSAL_TEXT_GAP_MS) {
        return;
    }
    s_refusal_text_sent = true;
    s_refusal_text_ms = now_ms;
    link_send_statustext(MAV_SEVERITY_WARNING, why);
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

void link_send_statustext(uint8_t severity, const UNITS_ROM char *text) { link_send_statustext_n(severity, text, 0xFFu); }

void link_send_statustext_n(uint8_t severity, const UNITS_ROM char *text, uint8_t n)
{
    mavlink_message_t msg;
    char t[50];
    memset(t, 0, sizeof t);
    uint8_t k = 0u;
    for (uint8_t i = 0; k < sizeof t && text[i] != '\0'; i++) {
        if (text[i] == '#' && n != 0xFFu) {
            if (n >= 10u && k < sizeof t) {
                t[k++] = (char)('0' + (n / 10u) % 10u);
            }
            if (k < sizeof t) {
                t[k++] = (char)('0' + n % 10u);
            }
            n = 0xFFu;
        } else {
            t[k++] = text[i];
        }
    }
    mavlink_msg_statustext_pack(s_cfg.sysid, s_cfg.compid, &msg, severity, t, 0, 0);
    (void)link_send(&msg);
}

static void send_command_ack(uint16_t command, uint8_t result, uint8_t reason, uint8_t to_sys, uint8_t to_comp)
{
    mavlink_message_t msg;
    mavlink_msg_command_ack_pack(s_cfg.sysid, s_cfg.compid, &msg, command, result, 0, reason, to_sys, to_comp);
    (void)link_send(&msg);
}

void link_storage_done(uint8_t done, uint8_t failed)
{
    if ((done & STORAGE_BIT(STORAGE_PARAMS)) != 0u) {
        send_command_ack(MAV_CMD_PREFLIGHT_STORAGE,
                         (failed & STORAGE_BIT(STORAGE_PARAMS)) != 0u ? MAV_RESULT_FAILED : MAV_RESULT_ACCEPTED, 0u,
                         s_state.storage_to_sys, s_state.storage_to_comp);
    }
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

/* Addressed to this robot: system ours (or 0 when broadcast is allowed), component ours or 0.
 * Another system's message is its business: ignored and counted in rx_other_target. One for a
 * component this system does not have is refused (counted, no answer: nobody here speaks for it). */
static bool addressed(uint8_t target_system, uint8_t target_component, bool broadcast_ok)
{
    bool sys = target_system == s_cfg.sysid || (target_system == 0u && broadcast_ok);
    bool comp = target_component == 0u || target_component == s_cfg.compid;
    if (!sys || !comp) {
        if (target_system == 0u && comp) {
            return false; /* broadcast where not allowed: the caller refuses it */
        }
        count(target_system == s_cfg.sysid ? &s_state.rx_refused : &s_state.rx_other_target);
        return false;
    }
    return true;
}

/* A message that must be addressed to this robot (motion, configuration, keys): broadcast is
 * refused with one STATUSTEXT, another robot's message ignored. */
static bool for_robot(uint8_t target_system, uint8_t target_component, uint32_t now_ms)
{
    if (addressed(target_system, target_component, false)) {
        return true;
    }
    if (target_system == 0u && (target_component == 0u || target_component == s_cfg.compid)) {
        refuse(LINK_TEXT("refused: broadcast, address the robot"), now_ms);
    }
    return false;
}

/* 0 or 1 exactly (flags and switches). */
static bool is_bool(float f) { return is_zero(f) || is_one(f); }

/* LINK_REFUSAL_* of params p[0..n-1] that must each be 0 or 1; 0 when fine. */
static uint8_t check_bools(const float *p, uint8_t n)
{
    for (uint8_t i = 0; i < n; i++) {
        if (!is_finite_f(p[i])) {
            return LINK_REFUSAL_NOT_FINITE;
        }
        if (!is_bool(p[i])) {
            return LINK_REFUSAL_OUT_OF_RANGE;
        }
    }
    return 0u;
}

/* One function per MAV_CMD: each checks its params (p: param1..3), acts, and returns the
 * LINK_REFUSAL_* reason, 0 when fine. */
static uint8_t cmd_estop(const mavlink_command_long_t *c, const float *p)
{
    uint8_t reason = check_bools(p, 1u);
    if (reason == 0u) {
        s_state.estop = is_one(c->param1);
    }
    return reason;
}

/* param2 (force) is not used: nothing bypasses the failsafe. */
static uint8_t cmd_arm_disarm(const mavlink_command_long_t *c, const float *p)
{
    uint8_t reason = check_bools(p, 1u);
    if (reason != 0u) {
        return reason;
    }
    if (is_one(c->param1)) {
        s_state.arm_request = true;
    } else {
        s_state.setpoint.valid = false;
        s_state.goal.active = false;
    }
    return 0u;
}

static uint8_t cmd_set_behaviours(const mavlink_command_long_t *c, const float *p)
{
    uint8_t reason = check_bools(p, 3u);
    if (reason == 0u) {
        s_state.behaviour_enable = (uint8_t)((is_one(c->param1) ? LINK_ENABLE_FOLLOW_WALL : 0u) |
                                             (is_one(c->param2) ? LINK_ENABLE_GOAL_SEEK : 0u) |
                                             (is_one(c->param3) ? LINK_ENABLE_AVOID : 0u));
        s_state.behaviour_gen++;
    }
    return reason;
}

/* param1: 0 read parameters back from EEPROM, 1 write them (boot-time ones such as DRIVE_KIND take
 * effect at the next boot): answered IN_PROGRESS at once, then ACCEPTED or FAILED when lib/storage has
 * written and read back both slots (link_storage_done()). Other param1 values: unsupported. */
static uint8_t cmd_preflight_storage(const mavlink_command_long_t *c, const mavlink_message_t *m, uint8_t *result)
{
    if (!is_finite_f(c->param1)) {
        return LINK_REFUSAL_NOT_FINITE;
    }
    if (is_one(c->param1)) {
        storage_request(STORAGE_PARAMS);
        s_state.storage_to_sys = m->sysid;
        s_state.storage_to_comp = m->compid;
        *result = MAV_RESULT_IN_PROGRESS;
    } else if (is_zero(c->param1)) {
        *result = storage_pending(STORAGE_PARAMS) ? MAV_RESULT_TEMPORARILY_REJECTED /* being written */
                  : params_load() == PARAMS_OK ? MAV_RESULT_ACCEPTED : MAV_RESULT_FAILED;
    } else {
        *result = MAV_RESULT_UNSUPPORTED;
        return LINK_REFUSAL_OUT_OF_RANGE;
    }
    return 0u;
}

static void handle_command(const mavlink_message_t *m)
{
    mavlink_command_long_t c;
    mavlink_msg_command_long_decode(m, &c);
    /* E-stop may be broadcast (stop every robot in the field); everything else is addressed. */
    if (!addressed(c.target_system, c.target_component, c.command == MAV_CMD_AGNAV_ESTOP)) {
        if (c.target_system == 0u && (c.target_component == 0u || c.target_component == s_cfg.compid)) {
            count(&s_state.rx_refused);
            send_command_ack(c.command, MAV_RESULT_DENIED, LINK_REFUSAL_BROADCAST, m->sysid, m->compid);
        }
        return;
    }
    const float p[3] = {c.param1, c.param2, c.param3};
    uint8_t result = MAV_RESULT_ACCEPTED;
    uint8_t reason;
    switch (c.command) {
    case MAV_CMD_AGNAV_ESTOP:
        reason = cmd_estop(&c, p);
        break;
    case MAV_CMD_COMPONENT_ARM_DISARM:
        reason = cmd_arm_disarm(&c, p);
        break;
    case MAV_CMD_AGNAV_SET_BEHAVIOURS:
        reason = cmd_set_behaviours(&c, p);
        break;
    case MAV_CMD_PREFLIGHT_STORAGE:
        reason = cmd_preflight_storage(&c, m, &result);
        break;
    default:
        result = MAV_RESULT_UNSUPPORTED;
        reason = LINK_REFUSAL_UNSUPPORTED;
        break;
    }
    if (reason != 0u) {
        count(&s_state.rx_refused);
        if (result == MAV_RESULT_ACCEPTED) {
            result = MAV_RESULT_DENIED;
        }
    }
    send_command_ack(c.command, result, reason, m->sysid, m->compid);
}

/* SETUP_SIGNING: set or clear the key. Accepted only when the frame was verified with the
 * current key, or (signed or not) while the provisioning window is open. */
static void handle_setup_signing(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_setup_signing_t ss;
    mavlink_msg_setup_signing_decode(m, &ss);
    if (!for_robot(ss.target_system, ss.target_component, now_ms)) {
        return;
    }
    bool verified = signing_state() == SIGNING_ON && (m->incompat_flags & MAVLINK_IFLAG_SIGNED) != 0u;
    bool window = s_provision_until_ms != 0u && (int32_t)(s_provision_until_ms - now_ms) > 0;
    if (!verified && !window) {
        refuse(LINK_TEXT("refused SETUP_SIGNING: not signed with the key"), now_ms);
        return;
    }
    signing_set_key(ss.secret_key, ss.initial_timestamp);
    if (signing_state() == SIGNING_ON) {
        link_send_statustext(MAV_SEVERITY_NOTICE, LINK_TEXT("signing: key set"));
    } else {
        link_send_statustext(MAV_SEVERITY_NOTICE, LINK_TEXT("signing: key cleared"));
    }
}

static void handle_param_set(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_param_set_t ps;
    mavlink_msg_param_set_decode(m, &ps);
    if (!for_robot(ps.target_system, ps.target_component, now_ms)) {
        return;
    }
    int16_t idx = params_find(ps.param_id);
    if (idx < 0) {
        count(&s_state.rx_refused);
        link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("refused PARAM_SET: unknown parameter"));
        return;
    }
    /* Outside +-2^24 a float no longer holds every integer and the int32 cast could overflow. */
    bool ok = FB_MAG(fbits(ps.param_value)) < FB_2P24; /* finite, > -16777216.0f and < 16777216.0f */
    int32_t v = ok ? round_half_away(ps.param_value) : 0;
    if (!ok || params_set((uint16_t)idx, v) != PARAMS_OK) {
        count(&s_state.rx_refused);
        if (ok) {
            link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("refused PARAM_SET: out of range"));
        } else {
            link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("refused PARAM_SET: not finite"));
        }
    }
    send_param((uint16_t)idx); /* the current value either way, as the protocol asks */
}

void link_behaviour_inputs(behaviour_in_t *in)
{
    const link_state_t *ls = &s_state;
    in->host_steer_cdeg = ls->setpoint.steer_cdeg;
    in->host_speed_mm_s = ls->setpoint.speed_mm_s;
    in->host_rx_ms = ls->setpoint.rx_ms;
    in->host_valid = ls->setpoint.valid;
    in->host_seq = ls->setpoint.seq;
    in->host_gen = ls->setpoint.gen;
    in->heartbeat_rx_ms = ls->host_heartbeat_ms;
    in->heartbeat_valid = ls->host_seen;
    in->manual_steer_cdeg = ls->manual.steer_cdeg;
    in->manual_speed_mm_s = ls->manual.speed_mm_s;
    in->manual_rx_ms = ls->manual.rx_ms;
    in->manual_valid = ls->manual.valid;
    in->manual_gen = ls->manual.gen;
    in->estop = ls->estop;
    in->goal_x_mm = ls->goal.x_mm;
    in->goal_y_mm = ls->goal.y_mm;
    in->goal_active = ls->goal.active;
    in->goal_gen = ls->goal.gen;
    in->mode_flags = ls->behaviour_enable;
    in->mode_gen = ls->behaviour_gen;
}

void link_set_manual_limits(int16_t max_steer_cdeg, int16_t max_speed_mm_s)
{
    s_cfg.manual_max_steer_cdeg = max_steer_cdeg;
    s_cfg.manual_max_speed_mm_s = max_speed_mm_s;
}

/* Only a ground station's: another robot on the same radio net (a fleet) must not keep this one's
 * link-loss failsafe quiet when its own host is gone. */
static void handle_heartbeat(const mavlink_message_t *m, uint32_t now_ms)
{
    if (m->sysid != s_cfg.sysid && mavlink_msg_heartbeat_get_type(m) == MAV_TYPE_GCS) {
        s_state.host_heartbeat_ms = now_ms;
        s_state.host_seen = true;
    }
}

/* Any message from the host that commands motion also counts as its heartbeat. */
static void host_heard(uint32_t now_ms)
{
    s_state.host_heartbeat_ms = now_ms;
    s_state.host_seen = true;
}

static void handle_drive_setpoint(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_agnav_drive_setpoint_t sp;
    mavlink_msg_agnav_drive_setpoint_decode(m, &sp);
    if (!for_robot(sp.target_system, sp.target_component, now_ms)) {
        return;
    }
    /* The PWM fields are checked in both modes (0 in physical mode): a field out of range is garbage. */
    bool ok = sp.mode <= AGNAV_DRIVE_RAW_PWM && sp.steer_cdeg >= -SETPOINT_STEER_LIMIT_CDEG &&
              sp.steer_cdeg <= SETPOINT_STEER_LIMIT_CDEG && sp.speed_mm_s >= -SETPOINT_SPEED_LIMIT_MM_S &&
              sp.speed_mm_s <= SETPOINT_SPEED_LIMIT_MM_S && sp.steer_pwm <= RAW_PWM_LIMIT &&
              sp.speed_pwm <= RAW_PWM_LIMIT;
    if (!ok) {
        s_state.setpoint.valid = false;
        refuse(LINK_TEXT("refused SETPOINT: out of range, stop"), now_ms);
        return;
    }
    s_state.setpoint.steer_cdeg = sp.steer_cdeg;
    s_state.setpoint.speed_mm_s = sp.speed_mm_s;
    s_state.setpoint.steer_pwm = sp.steer_pwm;
    s_state.setpoint.speed_pwm = sp.speed_pwm;
    s_state.setpoint.mode = sp.mode;
    s_state.setpoint.seq = sp.seq;
    s_state.setpoint.rx_ms = now_ms;
    s_state.setpoint.valid = true;
    s_state.setpoint.gen++;
    host_heard(now_ms);
}

static bool rc_released(uint16_t pulse_us) { return pulse_us == 0u || pulse_us == UINT16_MAX; }

static bool rc_valid(uint16_t pulse_us)
{
    return rc_released(pulse_us) || (pulse_us >= RC_VALID_MIN_US && pulse_us <= RC_VALID_MAX_US);
}

static void handle_rc_override(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_rc_channels_override_t rc;
    mavlink_msg_rc_channels_override_decode(m, &rc);
    if (!for_robot(rc.target_system, rc.target_component, now_ms)) {
        return;
    }
    if (!rc_valid(rc.chan1_raw) || !rc_valid(rc.chan3_raw)) {
        s_state.manual.valid = false;
        refuse(LINK_TEXT("refused RC: pulse not 800..2200 us, stop"), now_ms);
        return;
    }
    /* Channel 1 is roll/steering (right stick right = turn right = negative), channel 3 throttle. */
    s_state.manual.steer_cdeg = (int16_t)-link_rc_to_range(rc.chan1_raw, s_cfg.manual_max_steer_cdeg);
    s_state.manual.speed_mm_s = link_rc_to_range(rc.chan3_raw, s_cfg.manual_max_speed_mm_s);
    s_state.manual.rx_ms = now_ms;
    s_state.manual.valid = !(rc_released(rc.chan1_raw) && rc_released(rc.chan3_raw));
    s_state.manual.gen++;
    host_heard(now_ms);
}

static void handle_manual_control(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_manual_control_t mc;
    mavlink_msg_manual_control_decode(m, &mc);
    if (!for_robot(mc.target, 0u, now_ms)) {
        return;
    }
    /* x: forward stick -1000..1000; r: yaw stick, positive = clockwise = right.
     * INT16_MAX marks an axis as unused (MAVLink): it reads as centred. */
    int16_t x = mc.x == INT16_MAX ? 0 : mc.x;
    int16_t r = mc.r == INT16_MAX ? 0 : mc.r;
    if (x < -1000 || x > 1000 || r < -1000 || r > 1000) {
        s_state.manual.valid = false;
        refuse(LINK_TEXT("refused MANUAL: axis not +-1000, stop"), now_ms);
        return;
    }
    s_state.manual.speed_mm_s = (int16_t)(((int32_t)x * s_cfg.manual_max_speed_mm_s) / 1000);
    s_state.manual.steer_cdeg = (int16_t)(-((int32_t)r * s_cfg.manual_max_steer_cdeg) / 1000);
    s_state.manual.rx_ms = now_ms;
    s_state.manual.valid = true;
    s_state.manual.gen++;
    host_heard(now_ms);
}

/* A goal: position only, in the local frame (x and y used: type_mask bits 0, 1 clear), |x|, |y| <=
 * GOAL_LIMIT_M, which also rules out NaN and +-inf. NED in, REP-103 kept: y_left = -y_east. */
static void handle_position_target(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_set_position_target_local_ned_t t;
    mavlink_msg_set_position_target_local_ned_decode(m, &t);
    if (!for_robot(t.target_system, t.target_component, now_ms)) {
        return;
    }
    if (t.coordinate_frame != MAV_FRAME_LOCAL_NED || (t.type_mask & 0x3u) != 0u || FB_MAG(fbits(t.x)) > FB_10000 ||
        FB_MAG(fbits(t.y)) > FB_10000) {
        s_state.goal.active = false;
        refuse(LINK_TEXT("refused GOAL: frame/mask/NaN/10 km, dropped"), now_ms);
        return;
    }
    s_state.goal.x_mm = times_1000(t.x);  /* (int32_t)(t.x * 1000.0f) */
    s_state.goal.y_mm = -times_1000(t.y); /* (int32_t)(-t.y * 1000.0f) */
    s_state.goal.active = true;
    s_state.goal.gen++;
}

static void handle_param_request_list(const mavlink_message_t *m)
{
    if (addressed(mavlink_msg_param_request_list_get_target_system(m),
                  mavlink_msg_param_request_list_get_target_component(m), true)) {
        s_param_next = 0u; /* link_poll() sends the rows, PARAM_SEND_PER_POLL a call */
    }
}

static void handle_param_request_read(const mavlink_message_t *m, uint32_t now_ms)
{
    mavlink_param_request_read_t r;
    mavlink_msg_param_request_read_decode(m, &r);
    if (!addressed(r.target_system, r.target_component, true)) {
        return;
    }
    int16_t idx = r.param_index >= 0 ? r.param_index : params_find(r.param_id);
    if (idx >= 0 && (uint16_t)idx < params_count()) {
        send_param((uint16_t)idx);
    } else {
        refuse(LINK_TEXT("refused PARAM_READ: unknown parameter"), now_ms);
    }
}

/* AGNAV_CALIB_TABLE and AGNAV_CALIB_REQUEST: calib_service_on_msg (the link keeps no copy), which answers
 * each with an AGNAV_CALIB_ACK or the table; a broadcast is refused like any configuration message. */
static void handle_calib(const mavlink_message_t *m, uint32_t now_ms)
{
    bool table = m->msgid == MAVLINK_MSG_ID_AGNAV_CALIB_TABLE;
    uint8_t ts = table ? mavlink_msg_agnav_calib_table_get_target_system(m)
                       : mavlink_msg_agnav_calib_request_get_target_system(m);
    uint8_t tc = table ? mavlink_msg_agnav_calib_table_get_target_component(m)
                       : mavlink_msg_agnav_calib_request_get_target_component(m);
    if (s_cfg.on_calib != 0 && for_robot(ts, tc, now_ms) && s_cfg.on_calib(m)) {
        count(&s_state.rx_refused);
    }
}

/* One handler per message; ids not listed are parsed and ignored. Not inlined into link_feed(): the
 * handlers run in the link task only, never in the control tick. */
__attribute__((noinline)) static void handle(const mavlink_message_t *m, uint32_t now_ms)
{
    s_state.rx_frames++;
    switch (m->msgid) {
    case MAVLINK_MSG_ID_HEARTBEAT:
        handle_heartbeat(m, now_ms);
        break;
    case MAVLINK_MSG_ID_AGNAV_DRIVE_SETPOINT:
        handle_drive_setpoint(m, now_ms);
        break;
    case MAVLINK_MSG_ID_RC_CHANNELS_OVERRIDE:
        handle_rc_override(m, now_ms);
        break;
    case MAVLINK_MSG_ID_MANUAL_CONTROL:
        handle_manual_control(m, now_ms);
        break;
    case MAVLINK_MSG_ID_SET_POSITION_TARGET_LOCAL_NED:
        handle_position_target(m, now_ms);
        break;
    case MAVLINK_MSG_ID_COMMAND_LONG:
        handle_command(m);
        break;
    case MAVLINK_MSG_ID_PARAM_REQUEST_LIST:
        handle_param_request_list(m);
        break;
    case MAVLINK_MSG_ID_PARAM_REQUEST_READ:
        handle_param_request_read(m, now_ms);
        break;
    case MAVLINK_MSG_ID_SETUP_SIGNING:
        handle_setup_signing(m, now_ms);
        break;
    case MAVLINK_MSG_ID_PARAM_SET:
        handle_param_set(m, now_ms);
        break;
    case MAVLINK_MSG_ID_AGNAV_CALIB_TABLE:
    case MAVLINK_MSG_ID_AGNAV_CALIB_REQUEST:
        handle_calib(m, now_ms);
        break;
    default:
        break;
    }
}

/* Frames completed (any outcome) by link_feed: link_poll stops after one while signing is on. */
static uint8_t s_frames_done;

void link_feed(const uint8_t *data, uint16_t len, uint32_t now_ms)
{
    for (uint16_t i = 0; i < len; i++) {
        uint8_t r = mavlink_frame_char_buffer(&s_rx_msg, &s_rx_status, data[i], NULL, NULL);
        if (r != MAVLINK_FRAMING_INCOMPLETE) {
            s_frames_done++;
        }
        if (r == MAVLINK_FRAMING_OK) {
            handle(&s_rx_msg, now_ms);
        } else if (r == MAVLINK_FRAMING_BAD_SIGNATURE) {
            /* CRC fine, signature check failed (signing on): classify with the library's status. */
            if ((s_rx_msg.incompat_flags & MAVLINK_IFLAG_SIGNED) == 0u) {
                count(&s_state.rx_unsigned);
            } else if (s_rx_status.signing != NULL &&
                       s_rx_status.signing->last_status == MAVLINK_SIGNING_STATUS_BAD_SIGNATURE) {
                count(&s_state.rx_bad_signature);
            } else {
                count(&s_state.rx_replay); /* old timestamp, replay, or no free stream slot */
            }
        } else if (r == MAVLINK_FRAMING_BAD_CRC) {
            if (mavlink_get_msg_entry(s_rx_msg.msgid) == NULL) {
                count(&s_state.rx_unknown); /* an id the dialect does not have */
            } else {
                count(&s_state.rx_errors);
            }
        }
    }
}

/* SHA-256 blocks of a MAVLink 2 signature over len payload bytes: key 32 + header 10 +
 * payload + CRC 2 + link id 1 + timestamp 6, then 0x80 and the 64-bit length. */
static uint8_t sha_blocks(uint8_t len) { return (uint8_t)(((uint16_t)len + 123u) >> 6); }

static bool sha_fits(uint8_t blocks)
{
    return s_cfg.tick_due_us == 0 || (int32_t)(*s_cfg.tick_due_us - hal_time_us()) >=
                                         (int32_t)((uint16_t)(blocks * SIGNING_BLOCK_US) + SIGNING_MARGIN_US);
}

static bool tx_signed(void) { return mavlink_get_channel_status(MAVLINK_COMM_0)->signing != NULL; }

/* Whether a frame of len payload bytes may be packed now (its signature's hash fits). */
static bool tx_fits(uint8_t len) { return !tx_signed() || sha_fits(sha_blocks(len)); }

/* Blocks of the signed answer a received message may get (0 when answers go out unsigned):
 * COMMAND_ACK, PARAM_VALUE, STATUSTEXT all have <= 68 payload bytes (2 blocks). The streams
 * (HEARTBEAT, setpoints, RC / manual control) are answered only by a refusal text, at most one
 * per second, which is not budgeted. */
static uint8_t answer_blocks(uint32_t msgid)
{
    uint16_t id = (uint16_t)msgid;
    return !tx_signed() || id == MAVLINK_MSG_ID_HEARTBEAT || id == MAVLINK_MSG_ID_AGNAV_DRIVE_SETPOINT ||
                   id == MAVLINK_MSG_ID_MANUAL_CONTROL || id == MAVLINK_MSG_ID_RC_CHANNELS_OVERRIDE
               ? 0u
               : 2u;
}

/* link_poll calls the frame now in the parser has waited for a hash window. A frame bigger than
 * any window (or a tick that never leaves one) is hashed anyway after this many (> one control
 * period of 2 ms calls): the control tick is late once rather than the link stuck. */
#define LINK_SHA_MAX_WAITS 12u

/* 2 calls: one wait is normal (the link task runs just before the control tick, with no time
 * left); two mean the frame also missed the window after the tick. */
bool link_rx_waiting(void) { return s_sha_waits >= 2u; }

void link_poll(uint32_t now_ms)
{
    uint8_t buf[32];
    uint16_t n;
    if (signing_state() == SIGNING_OFF) {
        while ((n = hal_uart_read(HAL_UART_LINK, buf, sizeof buf)) > 0u) {
            link_feed(buf, n, now_ms);
        }
    } else {
        /* Each signed frame costs a SHA-256 (2-3 blocks of 2.8 ms on the AVR) when its last
         * signature byte arrives: take at most one frame per call, byte by byte, and hand
         * that last byte over only when the hash (and a signed answer) ends before the next
         * control tick; otherwise it stays queued in the UART (nothing lost or reordered) and
         * a later call takes it. The task runs every 2 ms; a 57600-baud link delivers a
         * 40-byte frame in ~7 ms. */
        s_frames_done = 0u;
        while (s_frames_done == 0u) {
            if (s_rx_status.signature_wait == 1u && s_sha_waits < LINK_SHA_MAX_WAITS &&
                !sha_fits((uint8_t)(sha_blocks(s_rx_msg.len) + answer_blocks(s_rx_msg.msgid)))) {
                s_sha_waits++;
                break;
            }
            if (hal_uart_read(HAL_UART_LINK, buf, 1u) != 1u) {
                break;
            }
            link_feed(buf, 1u, now_ms);
        }
        if (s_frames_done != 0u) {
            s_sha_waits = 0u;
        }
    }
    if (s_provision_until_ms != 0u && (int32_t)(s_provision_until_ms - now_ms) <= 0) {
        s_provision_until_ms = 0u; /* window closed: unsigned SETUP_SIGNING refused from now on */
        signing_set_provisioning(false);
    }
    signing_tick(now_ms);
    for (uint8_t k = 0; k < PARAM_SEND_PER_POLL && s_param_next < params_count() &&
                        tx_fits(MAVLINK_MSG_ID_PARAM_VALUE_LEN);
         k++) {
        send_param(s_param_next++);
    }
    if (s_param_next >= params_count()) {
        s_param_next = 0xFFFFu;
    }
}
