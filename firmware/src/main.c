/*
 * AgNav robot controller: wiring and the static scheduler table only.
 *
 * Every module lives in firmware/lib/<module>; this file connects them:
 *   link (MAVLink in) -> behaviour inputs; encoders -> odometry; sonar ring ->
 *   behaviour; behaviour out -> drive (calibration tables -> PWM); telemetry out.
 * EEPROM map: see params.h (calibration record, then parameters).
 */
#include <string.h>

#include "behaviour.h"
#include "calib.h"
#include "drive.h"
#include "encoder.h"
#include "hal.h"
#include "health.h"
#include "link.h"
#include "link_calib.h"
#include "odometry.h"
#include "params.h"
#include "sched.h"
#include "signing.h"
#include "sonar_ring.h"
#include "storage.h"

#define WATCHDOG_TIMEOUT_MS 250u
#define KEY_PROVISION_WINDOW_MS 10000u /* unsigned SETUP_SIGNING accepted this long after a power-on */
#define SONAR_STALE_MS 500u /* no new ring for this long -> sonar fault */

/* ---- parameters: each module declares its rows (lib/<module>/<module>_params.c, docs/parameters.md);
 * params_init() writes their defaults, params_load() the stored values over them ------------------ */
static const PARAMS_ROM param_group_ref_t PARAM_GROUPS[] = {
    &LINK_PARAM_GROUP,      /* SYSID_THISMAV */
    &DRIVE_PARAM_GROUP,     /* DRIVE_KIND, TRACK_MM */
    &ENCODER_PARAM_GROUP,   /* ENC_* */
    &ODOMETRY_PARAM_GROUP,  /* WHEELBASE_MM */
    &SONAR_RING_PARAM_GROUP, /* SONAR_COUNT */
    &BEHAVIOUR_PARAM_GROUP, /* BHV_MODES, the layers' tunables */
    &HEALTH_PARAM_GROUP,    /* HLTH_* */
    &SIGNING_PARAM_GROUP,   /* SIGN_TELEM */
};
#define PARAM_GROUP_COUNT ((uint8_t)(sizeof PARAM_GROUPS / sizeof PARAM_GROUPS[0]))

/* ---- state ---------------------------------------------------------------------------------- */
static behaviour_in_t s_in;
static behaviour_out_t s_out;
static uint32_t s_out_ms; /* tick time of s_out */
static uint32_t s_frame_ms;
static bool s_watchdog_boot;
static bool s_params_corrupt; /* stored parameters were corrupt: defaults in use (health flag) */
static const sonar_ring_cfg_t *s_ring;
static bool s_frame_fault; /* a sensor of the frame in s_in.sonar is SONAR_FAULT (set with the frame) */
static bool s_raw_out;     /* the last tick drove the raw PWM outputs of a host setpoint unchanged */

static void send(mavlink_message_t *msg) { (void)link_send(msg); }

/* ---- tasks ---------------------------------------------------------------------------------- */
/* The records lib/storage writes (map in storage.h). */
void storage_record_slots(uint8_t record, uint16_t *main_addr, uint16_t *copy_addr, uint16_t *len)
{
    if (record == STORAGE_PARAMS) {
        *main_addr = PARAMS_EEPROM_ADDR;
        *copy_addr = PARAMS_COPY_ADDR;
        *len = params_record_bytes();
    } else if (record == STORAGE_CALIB) {
        *main_addr = CALIB_EEPROM_ADDR;
        *copy_addr = CALIB_COPY_ADDR;
        *len = CALIB_RECORD_BYTES;
    } else {
        *main_addr = SIGNING_KEY_ADDR;
        *copy_addr = SIGNING_KEY_COPY_ADDR;
        *len = SIGNING_KEY_RECORD_BYTES;
    }
}

uint8_t storage_record_byte(uint8_t record, uint16_t pos)
{
    return record == STORAGE_PARAMS ? params_record_byte(pos)
           : record == STORAGE_CALIB ? calib_record_byte(pos) : signing_key_record_byte(pos);
}

static uint8_t s_calib_save_id; /* table id of the save request in progress (echoed in its final ack) */

static void send_calib_ack(uint8_t id, uint8_t result)
{
    mavlink_message_t msg;
    mavlink_msg_agnav_calib_ack_pack(link_sysid(), link_compid(), &msg, id, result, 255u, s_out.failsafe_flags);
    send(&msg);
}

/* AGNAV_CALIB_TABLE (write a table this output stage can drive) and AGNAV_CALIB_REQUEST (read: the
 * table is the answer; save: lib/storage writes the tables, answered IN_PROGRESS; defaults; any other
 * action is refused OUT_OF_RANGE), from link_poll(). Every message gets an answer; true when it was
 * refused (the link counts it). */
static bool on_calib(const mavlink_message_t *in)
{
    calib_table_t t;
    uint8_t id;
    uint8_t result;
    if (in->msgid == MAVLINK_MSG_ID_AGNAV_CALIB_TABLE) {
        mavlink_agnav_calib_table_t m;
        mavlink_msg_agnav_calib_table_decode(in, &m);
        id = m.table_id;
        result = link_calib_from_msg(&m, &t);
        if (result == 0u && !drive_table_fits(id, &t)) {
            result = AGNAV_CALIB_OUT_OF_RANGE; /* e.g. a table in servo microseconds: this stage takes 0..255 */
        }
        if (result == 0u) {
            result = link_calib_result(calib_set_table(id, &t));
        }
    } else {
        id = mavlink_msg_agnav_calib_request_get_table_id(in);
        uint8_t action = mavlink_msg_agnav_calib_request_get_action(in);
        if (action == AGNAV_CALIB_ACTION_SAVE) {
            storage_request(STORAGE_CALIB); /* the final answer comes from task_link when it is written */
            s_calib_save_id = id;
            result = AGNAV_CALIB_IN_PROGRESS;
        } else if (action == AGNAV_CALIB_ACTION_DEFAULTS) {
            result = calib_get_default(id, &t) ? link_calib_result(calib_set_table(id, &t)) : AGNAV_CALIB_BAD_TABLE;
        } else if (action != AGNAV_CALIB_ACTION_READ) {
            result = AGNAV_CALIB_OUT_OF_RANGE; /* no such action */
        } else if (calib_get_table(id, &t)) {
            mavlink_agnav_calib_table_t m;
            mavlink_message_t msg;
            link_calib_to_msg(id, &t, &m);
            mavlink_msg_agnav_calib_table_encode(link_sysid(), link_compid(), &msg, &m);
            send(&msg);
            return false;
        } else {
            result = AGNAV_CALIB_BAD_TABLE;
        }
    }
    send_calib_ack(id, result);
    return result != AGNAV_CALIB_ACCEPTED && result != AGNAV_CALIB_IN_PROGRESS;
}

static uint8_t s_param_changes; /* params_changes() when the modules last took the values */

/* PARAM_SET and PREFLIGHT_STORAGE (load) change the modules' parameter variables; the modules that
 * keep a copy or derive settings from them take the new values here, before the next control tick.
 * The robot's build (DRIVE_KIND, ENC_*, TRACK_MM, WHEELBASE_MM, SONAR_COUNT), SYSID_THISMAV and
 * BHV_MODES (the layers enabled at boot) wait for the next boot. */
static void apply_params(void)
{
    if (params_changes() == s_param_changes) {
        return;
    }
    s_param_changes = params_changes();
    behaviour_set_params(&behaviour_params);
    health_set_params(&health_params);
    link_set_manual_limits(behaviour_params.max_steer_cdeg, behaviour_params.max_speed_mm_s);
}

static void task_link(void)
{
    signing_set_sign_telemetry(signing_param_sign_telem != 0u); /* SIGN_TELEM applies at once */
    link_poll(hal_time_ms());
    storage_tick(); /* a saved record, a byte at a time: never waits for the EEPROM */
    uint8_t failed;
    uint8_t done = storage_take_done(&failed);
    if (done != 0u) {
        link_storage_done(done, failed);
        if ((done & STORAGE_BIT(STORAGE_CALIB)) != 0u) {
            bool ok = (failed & STORAGE_BIT(STORAGE_CALIB)) == 0u;
            calib_saved(ok);
            send_calib_ack(s_calib_save_id, ok ? AGNAV_CALIB_ACCEPTED : AGNAV_CALIB_STORAGE_ERROR);
        }
    }
    apply_params();
    link_state_t *ls = link_state();
    if (ls->arm_request) {
        ls->arm_request = false;
        behaviour_arm();
        health_clear(); /* a sensor still faulty latches again (docs/safety.md) */
    }
}

/* A fitted sensor that answered nothing (missing, unplugged, stuck line) leaves the robot
 * blind on that side: the failsafe stops it (SONAR_COUNT = 0 for a robot without sonars). */
static bool sonar_any_fault(const sonar_frame_t *f)
{
    for (uint8_t i = 0; i < f->count && i < SONAR_RING_MAX; i++) {
        if (f->status[i] == SONAR_FAULT) {
            return true;
        }
    }
    return false;
}

static void task_sonar(void)
{
    if (s_ring == 0) {
        return;
    }
    sonar_ring_step(hal_time_us());
}

/* A completed ring frame into the behaviour inputs and the health monitor. Its own row, after the
 * control task: in a pass where a frame completes just as the control tick falls due, the tick runs
 * first and the frame's work (up to ~270 us on the AVR) after it, instead of delaying the tick. */
static void task_sonar_frame(void)
{
    if (s_ring == 0) {
        return;
    }
    /* Straight into the behaviour inputs: tasks run one at a time, so the control
     * task never sees a half-written frame. */
    if (sonar_ring_snapshot(&s_in.sonar)) {
        s_frame_ms = hal_time_ms();
        health_sonar(&s_in.sonar);
        s_frame_fault = sonar_any_fault(&s_in.sonar);
        behaviour_sonar_frame(&s_in.sonar); /* follow-wall sums here, not in the control tick */
    }
}

/* Wheel travel in one control tick beyond this (10 m/s at 20 ms) is no wheel of an AgNav robot:
 * a noisy or shorted encoder line. It is clamped before odometry (whose integration work grows
 * with the distance: a 20 kHz storm of Hall pulses took 1.9 M cycles, 121 ms, per tick on the
 * AVR and the watchdog reset the board) and reported to the health monitor as an encoder error. */
#define ODOM_MAX_TICK_UM 200000L
static uint8_t s_implausible; /* bit i: wheel i's travel was clamped this tick */

/* count_lo / edges_lo: the low 16 bits of each wheel's count and edge total as this update
 * folded them, for the health check (no second fold of the interrupt records per tick). */
static void update_odometry(uint16_t *count_lo, uint16_t *edges_lo)
{
    encoder_update(hal_time_us());
    encoder_motion_t m[ENCODER_MAX];
    s_implausible = 0u;
    for (uint8_t i = 0; i < encoder_params.count; i++) {
        encoder_motion(i, &m[i]);
        count_lo[i] = (uint16_t)m[i].count;
        edges_lo[i] = (uint16_t)m[i].edges;
        if (m[i].delta_um > ODOM_MAX_TICK_UM || m[i].delta_um < -ODOM_MAX_TICK_UM) {
            m[i].delta_um = m[i].delta_um > 0 ? ODOM_MAX_TICK_UM : -ODOM_MAX_TICK_UM;
            s_implausible = (uint8_t)(s_implausible | (1u << i));
        }
    }
    if (drive_params.kind == DRIVE_DIFFERENTIAL && encoder_params.count >= 2u) {
        int32_t l_um = m[0].delta_um, r_um = m[1].delta_um;
        int32_t l_v = m[0].speed_mm_s, r_v = m[1].speed_mm_s;
        if (encoder_params.count >= 4u) { /* skid steer: wheels 2 (left) and 3 (right) averaged in */
            /* >> 1, not / 2: avr-gcc -Os calls a ~600-cycle division routine for a signed / 2. */
            l_um = (l_um + m[2].delta_um) >> 1;
            r_um = (r_um + m[3].delta_um) >> 1;
            l_v = (l_v + m[2].speed_mm_s) >> 1;
            r_v = (r_v + m[3].speed_mm_s) >> 1;
        }
        odom_update_diff(l_um, r_um, l_v, r_v);
    } else {
        int32_t rear_um = m[0].delta_um, rear_v = m[0].speed_mm_s;
        if (encoder_params.count >= 2u) { /* two rear wheels: their mean is the axle centre */
            rear_um = (rear_um + m[1].delta_um) >> 1;
            rear_v = (rear_v + m[1].speed_mm_s) >> 1;
        }
        odom_update_ackermann(rear_um, s_out.steer_cdeg, rear_v);
    }
}

/* Encoder health, before this tick's command: "driving" is what the outputs did since the
 * last tick (not neutral: the calibration dead band already maps too-slow requests to neutral). */
static void check_encoders(uint32_t now_ms, const uint16_t *count, const uint16_t *edges)
{
    const drive_output_t *d = drive_output();
    /* Not in calibration mode (raw PWM): its sweep drives below the motion threshold on purpose. */
    bool driving = !s_raw_out && s_out.speed_mm_s != 0 &&
                   (drive_params.kind == DRIVE_DIFFERENTIAL ? (d->left_duty | d->right_duty) != 0u : d->throttle_us != 1500u);
    health_encoders(now_ms, driving, count, edges, (uint8_t)(encoder_faults() | s_implausible));
}

/* One STATUSTEXT per newly latched health bit, at most one per control tick (twelve sonars
 * failing together would otherwise send twelve frames in one tick). */
static void report_health(void)
{
    uint32_t fresh = health_take_new();
    for (uint8_t b = 0; fresh != 0u && b < 32u; b++, fresh >>= 1) {
        if ((fresh & 1u) == 0u) {
            continue;
        }
        if (b < HEALTH_ENC_ERROR_SHIFT) {
            link_send_statustext_n(MAV_SEVERITY_ERROR, LINK_TEXT("health: encoder # no counts while driving, stop"), b);
        } else if (b < HEALTH_SONAR_TIMEOUT_SHIFT) {
            link_send_statustext_n(MAV_SEVERITY_ERROR, LINK_TEXT("health: encoder # illegal edges/storm, stop"),
                                   (uint8_t)(b - HEALTH_ENC_ERROR_SHIFT));
        } else if (b < HEALTH_SONAR_ZERO_SHIFT) {
            link_send_statustext_n(MAV_SEVERITY_ERROR, LINK_TEXT("health: sonar # never echoes, stop"),
                                   (uint8_t)(b - HEALTH_SONAR_TIMEOUT_SHIFT));
        } else {
            link_send_statustext_n(MAV_SEVERITY_ERROR, LINK_TEXT("health: sonar # reads zero, stop"),
                                   (uint8_t)(b - HEALTH_SONAR_ZERO_SHIFT));
        }
        return;
    }
}

static void task_control(void)
{
    uint32_t now_ms = hal_time_ms();
    hal_watchdog_kick();
    uint16_t count_lo[ENCODER_MAX], edges_lo[ENCODER_MAX];
    update_odometry(count_lo, edges_lo);
    check_encoders(now_ms, count_lo, edges_lo);
    report_health();

    behaviour_in_t *in = &s_in; /* the sonar frame is written by task_sonar_frame */
    in->now_ms = now_ms;
    link_behaviour_inputs(in);
    const link_state_t *ls = link_state();
    const link_setpoint_t *sp = &ls->setpoint;
    int8_t raw_dir = sp->speed_mm_s < 0 ? -1 : 1;
    if (sp->mode == AGNAV_DRIVE_RAW_PWM) { /* the layers and their limits see what the raw outputs drive */
        drive_raw_physical(sp->steer_pwm, sp->speed_pwm, raw_dir, &in->host_steer_cdeg, &in->host_speed_mm_s);
    }
    odom_behaviour_inputs(in);
    in->encoder_fault = encoder_faults() != 0u || health_encoder_fault();
    in->sonar_fault = s_ring != 0 && ((uint32_t)(now_ms - s_frame_ms) > SONAR_STALE_MS || s_frame_fault ||
                                      health_sonar_fault());
    in->reset_was_watchdog = s_watchdog_boot;
    /* "Stored configuration not in use": calibration defaulted, or a corrupt parameter record. */
    in->calib_defaulted = (calib_health() & CALIB_DEFAULTED) != 0u || s_params_corrupt;

    behaviour_step(in, &s_out);

    /* A raw setpoint within the limits drives its outputs unchanged; one beyond them (or a
     * clamped one) drives the limited physical command through the tables, which is also what
     * BEHAVIOUR_STATUS reports: one limiter for every source. */
    bool raw = s_out.layer == BHV_LAYER_HOST_COMMAND && sp->mode == AGNAV_DRIVE_RAW_PWM &&
               s_out.speed_mm_s == in->host_speed_mm_s && s_out.steer_cdeg == in->host_steer_cdeg;
    s_raw_out = raw;
    if (raw) {
        drive_apply_raw(sp->steer_pwm, sp->speed_pwm, raw_dir);
    } else if (s_out.speed_mm_s == 0 && s_out.layer == BHV_LAYER_FAILSAFE) {
        drive_stop();
    } else {
        drive_apply(s_out.steer_cdeg, s_out.speed_mm_s);
    }
    if (encoder_params.mode == ENCODER_MODE_HALL) { /* the hint only signs Hall pulses */
        const drive_output_t *o = drive_output();
        for (uint8_t i = 0; i < encoder_params.count; i++) {
            int8_t hint = o->direction;
            if (drive_params.kind == DRIVE_DIFFERENTIAL && !raw) { /* per side: a turn on the spot spins them apart */
                int16_t side = (i & 1u) != 0u ? o->right_mm_s : o->left_mm_s; /* wheels 0, 2 left; 1, 3 right */
                hint = side > 0 ? 1 : side < 0 ? -1 : 0; /* 0: keeps the last sign while stopping */
            }
            encoder_set_direction_hint(i, hint);
        }
    }
    s_out_ms = now_ms;
}

/* The active layer and its reason, checked every control tick (runs right after task_control):
 * sent in the tick a layer, reason or failsafe flag changes, and at STATUS_KEEPALIVE_MS
 * otherwise. Sending all 50 per second would take 1.2 kB/s of the ~1.5 kB/s a 57600-baud radio
 * has for telemetry; this way the host still learns every change in the tick it happens. */
#define STATUS_KEEPALIVE_MS 200u
static behaviour_out_t s_sent;
static uint32_t s_sent_ms;

static void task_telemetry_50hz(void)
{
    bool changed = s_out.layer != s_sent.layer || s_out.reason != s_sent.reason ||
                   s_out.failsafe_flags != s_sent.failsafe_flags;
    if (!changed && (uint32_t)(s_out_ms - s_sent_ms) < STATUS_KEEPALIVE_MS) {
        return;
    }
    mavlink_message_t msg;
    mavlink_msg_agnav_behaviour_status_pack(link_sysid(), link_compid(), &msg, s_out_ms, s_out.layer, s_out.reason,
                                            s_out.failsafe_flags, s_out.steer_cdeg, s_out.speed_mm_s);
    if (link_send(&msg)) {
        s_sent = s_out;
        s_sent_ms = s_out_ms;
    }
}

static void send_encoder_status(uint32_t now_ms)
{
    mavlink_message_t msg;
    int32_t count[4] = {0, 0, 0, 0};
    int16_t speed[4] = {0, 0, 0, 0};
    uint16_t errors[4] = {0, 0, 0, 0};
    for (uint8_t i = 0; i < encoder_params.count; i++) {
        encoder_snapshot_t snap;
        encoder_motion_t m;
        encoder_snapshot(i, &snap);
        encoder_motion(i, &m);
        count[i] = snap.count;
        speed[i] = (int16_t)m.speed_mm_s;
        errors[i] = (uint16_t)snap.errors;
    }
    mavlink_msg_agnav_encoder_status_pack(link_sysid(), link_compid(), &msg, now_ms, count, speed, errors, encoder_params.count);
    send(&msg);
}

#define TASK_COUNT 6u
#define TASK_CONTROL 2u /* row of task_control in TASKS */
static const sched_task_t TASKS[TASK_COUNT]; /* the table, defined below */
static sched_stats_t s_stats[TASK_COUNT];
static uint8_t s_stats_next;

/* The 1 Hz messages, one per call (HEARTBEAT first, at t = 0, 1 s, ...). */
static uint8_t s_telem1_phase;

static void send_telemetry_1hz(void)
{
    mavlink_message_t msg;
    uint8_t phase = s_telem1_phase;
    s_telem1_phase = (uint8_t)((phase + 1u) & 3u);
    if (phase == 0u) {
        uint8_t state = (s_out.failsafe_flags & BHV_FS_STOP_MASK) != 0u ? MAV_STATE_CRITICAL : MAV_STATE_ACTIVE;
        mavlink_msg_heartbeat_pack(link_sysid(), link_compid(), &msg, MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC,
                                   MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, s_out.layer, state);
    } else if (phase == 1u) {
        /* SYS_STATUS for ground stations: sensors present / enabled / healthy (proximity = sonar
         * ring, motor outputs = drive), the link's receive errors as its drop rate proxy, and
         * errors_count1..4: link refusals, unsigned / wrongly signed / replayed frames dropped. */
        uint32_t present = MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS | (s_ring != 0 ? MAV_SYS_STATUS_SENSOR_PROXIMITY : 0u);
        uint32_t healthy = present;
        if ((s_out.failsafe_flags & BHV_FS_SONAR_FAULT) != 0u) {
            healthy &= ~(uint32_t)MAV_SYS_STATUS_SENSOR_PROXIMITY;
        }
        if ((s_out.failsafe_flags & BHV_FS_ENCODER_FAULT) != 0u) {
            healthy &= ~(uint32_t)MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS;
        }
        const link_state_t *ls = link_state();
        uint32_t dropped = (uint32_t)ls->rx_errors + ls->rx_unknown; /* errors_comm: every frame the parser dropped */
        mavlink_msg_sys_status_pack(link_sysid(), link_compid(), &msg, present, present, healthy, 0u, 0u, -1, -1, 0u,
                                    (uint16_t)(dropped > UINT16_MAX ? UINT16_MAX : dropped), ls->rx_refused,
                                    ls->rx_unsigned, ls->rx_bad_signature, ls->rx_replay, 0u, 0u, 0u);
    } else {
        /* Phase 2: which sensor failed how (NAMED_VALUE_INT "HEALTH", health.h bit layout).
         * Phase 3: one scheduler task's worst run time per second, round robin ("T_<name>", us).
         * One pack call for both (the pack copies all 10 bytes of the name). */
        char name[10] = {'H', 'E', 'A', 'L', 'T', 'H', 0, 0, 0, 0};
        int32_t value = (int32_t)health_bits();
        if (phase == 3u) {
            const char *n = TASKS[s_stats_next].name;
            name[0] = 'T';
            name[1] = '_';
            bool end = false;
            for (uint8_t k = 0; k < 8u; k++) {
                end = end || n[k] == '\0';
                name[2u + k] = end ? '\0' : n[k];
            }
            value = (int32_t)s_stats[s_stats_next].worst_us;
            s_stats_next = (uint8_t)((s_stats_next + 1u) % TASK_COUNT);
        }
        mavlink_msg_named_value_int_pack(link_sysid(), link_compid(), &msg, hal_time_ms(), name, value);
    }
    send(&msg);
}

/* The 10 Hz and 1 Hz telemetry: one frame per 20 ms call, in a fixed rotation of five 20 ms
 * slots per 100 ms round (docs/safety.md "Signing": with SIGN_TELEM each signed frame costs
 * ~5.7 ms of SHA-256 on the AVR; one per tick, after the control tick and BEHAVIOUR_STATUS,
 * leaves the rest of the 20 ms period to the link task's verification of received frames):
 *   slot 0: the 1 Hz messages, one per 200 ms (rounds 0, 2, 4, 6 of each second)
 *   slot 1: AGNAV_ODOMETRY (10 Hz)
 *   slot 2: AGNAV_ENCODER_STATUS (2 Hz, rounds 4, 9) or LOCAL_POSITION_NED (2 Hz, rounds 1, 6)
 *   slot 3: AGNAV_SONAR_RING (10 Hz, when fitted)
 *   slot 4: nothing */
static uint8_t s_telem_slot;  /* 0..4 */
static uint8_t s_telem_round; /* 0..9 */
static bool s_telem_yielded;  /* the last call left its slot to the link */

static void task_telemetry(void)
{
    if (link_rx_waiting() && !s_telem_yielded) {
        s_telem_yielded = true; /* a received frame needs the time (docs/safety.md "Signing"): */
        return;                 /* this slot next tick, never two ticks in a row */
    }
    s_telem_yielded = false;
    uint8_t slot = s_telem_slot;
    uint8_t round = s_telem_round;
    if (slot >= 4u) {
        s_telem_slot = 0u;
        s_telem_round = round >= 9u ? 0u : (uint8_t)(round + 1u);
    } else {
        s_telem_slot = (uint8_t)(slot + 1u);
    }
    uint32_t now_ms = hal_time_ms();
    mavlink_message_t msg;
    if (slot == 0u) {
        if ((round & 1u) == 0u && round < 8u) {
            send_telemetry_1hz();
        } else if (round == 9u) {
            /* once a second at rest (nothing commanded, wheels still): storage upkeep that would
             * stall the loop while driving (hal.h) */
            odom_pose_t pose;
            odom_get(&pose);
            if (s_out.speed_mm_s == 0 && pose.speed_mm_s == 0) {
                hal_eeprom_idle();
            }
        }
        return;
    }
    if (slot == 3u) {
        if (s_ring != 0 && s_in.sonar.seq != 0u) {
            mavlink_msg_agnav_sonar_ring_pack(link_sysid(), link_compid(), &msg, s_frame_ms, s_in.sonar.ranges_mm,
                                              s_in.sonar.status, s_in.sonar.count, (uint16_t)s_in.sonar.seq);
            send(&msg);
        }
        return;
    }
    if (slot == 4u) {
        return;
    }
    odom_pose_t pose;
    odom_get(&pose);
    if (slot == 1u) {
        mavlink_msg_agnav_odometry_pack(link_sysid(), link_compid(), &msg, now_ms, pose.x_mm, pose.y_mm,
                                        (int16_t)pose.heading_cdeg, (int16_t)pose.speed_mm_s,
                                        (int16_t)pose.yaw_rate_cdeg_s);
        send(&msg);
    } else if (round == 4u || round == 9u) {
        send_encoder_status(now_ms);
    } else if (round == 1u || round == 6u) {
        /* The standard LOCAL_POSITION_NED for ground stations (NED from REP-103: y_east = -y_left). */
        int32_t c = behaviour_cos_q14(pose.heading_cdeg), sn = behaviour_sin_q14(pose.heading_cdeg);
        float v = (float)pose.speed_mm_s * 0.001f;
        mavlink_msg_local_position_ned_pack(link_sysid(), link_compid(), &msg, now_ms, (float)pose.x_mm * 0.001f,
                                            -(float)pose.y_mm * 0.001f, 0.0f, v * (float)c / 16384.0f,
                                            -v * (float)sn / 16384.0f, 0.0f);
        send(&msg);
    }
}

/* The static scheduler table: {task, period ms, budget us, name}. */
static const sched_task_t TASKS[TASK_COUNT] = {
    {task_link, 2u, 600u, "link"},
    {task_sonar, 1u, 350u, "sonar"}, /* worst 320 us measured, interrupts included */
    {task_control, 20u, 1000u, "control"},
    {task_sonar_frame, 1u, 300u, "sonframe"},
    {task_telemetry_50hz, 20u, 300u, "telem50"},
    {task_telemetry, 20u, 800u, "telem"},
};
_Static_assert(sizeof TASKS / sizeof TASKS[0] == TASK_COUNT, "TASK_COUNT matches the table");

/* Boot report: once, as STATUSTEXT (docs/safety.md "Controller faults"). */
static void report_boot(hal_reset_cause_t cause)
{
    switch (cause) {
    case HAL_RESET_POWER_ON:
        link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("boot: power-on reset"));
        break;
    case HAL_RESET_WATCHDOG:
        link_send_statustext(MAV_SEVERITY_CRITICAL, LINK_TEXT("boot: WATCHDOG reset, stopped until armed"));
        break;
    case HAL_RESET_EXTERNAL:
        link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("boot: external reset"));
        break;
    case HAL_RESET_BROWN_OUT:
        link_send_statustext(MAV_SEVERITY_CRITICAL, LINK_TEXT("boot: BROWN-OUT reset, stopped until armed"));
        break;
    default:
        link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("boot: reset of unknown cause"));
        break;
    }
    if (!hal_clock_from_crystal()) { /* serial bit rates and timings off by the RC oscillator's error */
        link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("boot: no crystal, clock from HSI (+-1 %)"));
    }
}

void agnav_setup(void)
{
    hal_init();
    /* A reset the robot did not ask for (watchdog: a hung loop; brown-out: the supply sagged,
     * e.g. motors stalling a weak battery) may have come in mid-motion: boot stopped, and stay
     * stopped until the host arms again (behaviour's watchdog-boot latch). */
    hal_reset_cause_t cause = hal_reset_cause();
    s_watchdog_boot = cause == HAL_RESET_WATCHDOG || cause == HAL_RESET_BROWN_OUT;
    /* A reset is a fresh start: clear what main keeps between ticks (on the board .bss is
     * zeroed anyway; the native SIL re-enters agnav_setup() without reloading the program). */
    memset(&s_in, 0, sizeof s_in);
    memset(&s_out, 0, sizeof s_out);
    memset(&s_sent, 0, sizeof s_sent);
    s_frame_fault = false;
    s_raw_out = false;
    s_out_ms = s_sent_ms = 0u;
    s_stats_next = 0u;
    s_telem1_phase = 0u;
    s_telem_slot = s_telem_round = 0u;
    s_frame_ms = hal_time_ms();
    params_init(PARAM_GROUPS, PARAM_GROUP_COUNT);
    storage_init();
    params_result_t params_rc = params_load();
    s_params_corrupt = params_rc == PARAMS_CORRUPT;

    calib_init();
    calib_load();
    /* A stored table this output stage cannot drive (written by an older firmware, e.g. in servo
     * microseconds: full throttle here) is replaced by its default, as the link refuses such writes. */
    for (uint8_t id = 0; id < (uint8_t)CALIB_TABLE_COUNT; id++) {
        calib_table_t t;
        if (calib_get_table(id, &t) && !drive_table_fits(id, &t)) {
            calib_use_default(id);
        }
    }

    encoder_init_params(&encoder_params);
    odom_cfg_t oc = {drive_params.kind == DRIVE_DIFFERENTIAL ? ODOM_MODEL_DIFF : ODOM_MODEL_ACKERMANN,
                     drive_params.track_mm, odom_param_wheelbase_mm};
    odom_init(&oc);
    s_ring = sonar_ring_for_count(sonar_ring_param_count);
    if (s_ring != 0) {
        sonar_ring_init(s_ring);
    }
    behaviour_init(&behaviour_params, s_ring);
    health_init(&health_params, encoder_params.count);
    s_param_changes = params_changes();
    drive_init(&drive_params);

    /* The signing key may be provisioned unsigned only right after a power-on or external
     * reset: on the Mega, opening the USB serial port resets the board (DTR auto-reset), so
     * this is "someone at the robot with a cable". Watchdog / brown-out boots: no window. */
    uint16_t window_ms = (cause == HAL_RESET_POWER_ON || cause == HAL_RESET_EXTERNAL) ? KEY_PROVISION_WINDOW_MS : 0u;
    link_cfg_t lc = {link_param_sysid,
                     MAV_COMP_ID_AUTOPILOT1,
                     behaviour_params.max_steer_cdeg,
                     behaviour_params.max_speed_mm_s,
                     on_calib,
                     window_ms,
                     &s_stats[TASK_CONTROL].next_due_us};
    hal_uart_init(HAL_UART_LINK, 57600u);
    link_init(&lc);
    signing_set_sign_telemetry(signing_param_sign_telem != 0u); /* before the boot report goes out */
    link_state()->behaviour_enable = behaviour_boot_modes;
    report_boot(cause);
    if (signing_state() == SIGNING_KEY_CORRUPT) {
        link_send_statustext(MAV_SEVERITY_CRITICAL, LINK_TEXT("signing: key record corrupt, all frames refused; re-provision"));
    }
    if ((calib_health() & CALIB_DEFAULTED) != 0u) {
        link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("calib: EEPROM tables bad or unfit, defaults in use"));
    }
    if (s_params_corrupt) {
        link_send_statustext(MAV_SEVERITY_ERROR, LINK_TEXT("params: EEPROM record corrupt, defaults in use"));
    } else if (params_rc != PARAMS_OK) {
        link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("params: no stored parameters, defaults in use"));
    }
    sched_init(TASKS, (uint8_t)TASK_COUNT, s_stats);
    hal_watchdog_start(WATCHDOG_TIMEOUT_MS);
}

void agnav_loop_once(void) { (void)sched_run(hal_time_us()); }

#ifndef AGNAV_NO_MAIN
int main(void)
{
    agnav_setup();
    for (;;) {
        agnav_loop_once();
        uint32_t now = hal_time_us();
        hal_idle_until(now + sched_idle_us(now)); /* sleep until the next task is due */
    }
}
#endif
