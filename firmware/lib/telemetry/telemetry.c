/* The robot's own reports over the link, see telemetry.h. */
#include "telemetry.h"

#include <string.h>

#include "behaviour.h"
#include "calib.h"
#include "control.h"
#include "encoder.h"
#include "health.h"
#include "link.h"
#include "odometry.h"
#include "sched.h"
#include "signing.h"

static behaviour_out_t s_sent; /* the last BEHAVIOUR_STATUS sent */
static uint32_t s_sent_ms;
static uint8_t s_stats_next;   /* scheduler row of the next "T_<task>" report */
static uint8_t s_telem1_phase; /* the next 1 Hz message, 0..3 */
static uint8_t s_telem_slot;   /* 0..4 */
static uint8_t s_telem_cycle;  /* 0..9 */
static bool s_telem_yielded;   /* the last call left its slot to the link */

static void send(mavlink_message_t *msg) { (void)link_send(msg); }

void telemetry_reset(void)
{
    memset(&s_sent, 0, sizeof s_sent);
    s_sent_ms = 0u;
    s_stats_next = 0u;
    s_telem1_phase = 0u;
    s_telem_slot = s_telem_cycle = 0u;
}

void telemetry_task_50hz(void)
{
    const behaviour_out_t *out = control_out();
    uint32_t out_ms = control_out_ms();
    bool changed = out->layer != s_sent.layer || out->reason != s_sent.reason ||
                   out->failsafe_flags != s_sent.failsafe_flags;
    if (!changed && (uint32_t)(out_ms - s_sent_ms) < TELEMETRY_STATUS_KEEPALIVE_MS) {
        return;
    }
    mavlink_message_t msg;
    mavlink_msg_agnav_behaviour_status_pack(link_sysid(), link_compid(), &msg, out_ms, out->layer, out->reason,
                                            out->failsafe_flags, out->steer_cdeg, out->speed_mm_s);
    if (link_send(&msg)) {
        s_sent = *out;
        s_sent_ms = out_ms;
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
    mavlink_msg_agnav_encoder_status_pack(link_sysid(), link_compid(), &msg, now_ms, count, speed, errors,
                                          encoder_params.count);
    send(&msg);
}

/* The 1 Hz messages, one per call (HEARTBEAT first, at t = 0, 1 s, ...). */
static void send_telemetry_1hz(void)
{
    mavlink_message_t msg;
    const behaviour_out_t *out = control_out();
    uint8_t phase = s_telem1_phase;
    s_telem1_phase = (uint8_t)((phase + 1u) & 3u);
    if (phase == 0u) {
        uint8_t state = (out->failsafe_flags & BHV_FS_STOP_MASK) != 0u ? MAV_STATE_CRITICAL : MAV_STATE_ACTIVE;
        mavlink_msg_heartbeat_pack(link_sysid(), link_compid(), &msg, MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC,
                                   MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, out->layer, state);
    } else if (phase == 1u) {
        /* SYS_STATUS for ground stations: sensors present / enabled / healthy (proximity = sonar
         * ring, motor outputs = drive), the link's receive errors as its drop rate proxy, and
         * errors_count1..4: link refusals, unsigned / wrongly signed / replayed frames dropped. */
        uint32_t present = MAV_SYS_STATUS_SENSOR_MOTOR_OUTPUTS |
                           (control_sonar_frame() != 0 ? MAV_SYS_STATUS_SENSOR_PROXIMITY : 0u);
        uint32_t healthy = present;
        if ((out->failsafe_flags & BHV_FS_SONAR_FAULT) != 0u) {
            healthy &= ~(uint32_t)MAV_SYS_STATUS_SENSOR_PROXIMITY;
        }
        if ((out->failsafe_flags & BHV_FS_ENCODER_FAULT) != 0u) {
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
            const char *n = sched_task(s_stats_next)->name;
            name[0] = 'T';
            name[1] = '_';
            bool end = false;
            for (uint8_t k = 0; k < 8u; k++) {
                end = end || n[k] == '\0';
                name[2u + k] = end ? '\0' : n[k];
            }
            value = (int32_t)sched_task_stats(s_stats_next)->worst_us;
            uint8_t next = (uint8_t)(s_stats_next + 1u);
            s_stats_next = next < sched_task_count() ? next : 0u;
        }
        mavlink_msg_named_value_int_pack(link_sysid(), link_compid(), &msg, hal_time_ms(), name, value);
    }
    send(&msg);
}

void telemetry_task(void)
{
    if (link_rx_waiting() && !s_telem_yielded) {
        s_telem_yielded = true; /* a received frame needs the time (docs/safety.md "Signing"): */
        return;                 /* this slot next tick, never two ticks in a row */
    }
    s_telem_yielded = false;
    uint8_t slot = s_telem_slot;
    uint8_t cycle = s_telem_cycle;
    if (slot >= 4u) {
        s_telem_slot = 0u;
        s_telem_cycle = cycle >= 9u ? 0u : (uint8_t)(cycle + 1u);
    } else {
        s_telem_slot = (uint8_t)(slot + 1u);
    }
    uint32_t now_ms = hal_time_ms();
    mavlink_message_t msg;
    if (slot == 0u) {
        if ((cycle & 1u) == 0u && cycle < 8u) {
            send_telemetry_1hz();
        } else if (cycle == 9u) {
            /* once a second at rest (nothing commanded, wheels still): storage upkeep that would
             * stall the loop while driving (hal.h) */
            odom_pose_t pose;
            odom_get(&pose);
            if (control_out()->speed_mm_s == 0 && pose.speed_mm_s == 0) {
                hal_eeprom_idle();
            }
        }
        return;
    }
    if (slot == 3u) {
        const sonar_frame_t *f = control_sonar_frame();
        if (f != 0 && f->seq != 0u) {
            mavlink_msg_agnav_sonar_ring_pack(link_sysid(), link_compid(), &msg, control_sonar_frame_ms(), f->ranges_mm,
                                              f->status, f->count, (uint16_t)f->seq);
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
    } else if (cycle == 4u || cycle == 9u) {
        send_encoder_status(now_ms);
    } else if (cycle == 1u || cycle == 6u) {
        /* The standard LOCAL_POSITION_NED for ground stations (NED from REP-103: y_east = -y_left). */
        int32_t c = behaviour_cos_q14(pose.heading_cdeg), sn = behaviour_sin_q14(pose.heading_cdeg);
        float v = (float)pose.speed_mm_s * 0.001f;
        mavlink_msg_local_position_ned_pack(link_sysid(), link_compid(), &msg, now_ms, (float)pose.x_mm * 0.001f,
                                            -(float)pose.y_mm * 0.001f, 0.0f, v * (float)c / 16384.0f,
                                            -v * (float)sn / 16384.0f, 0.0f);
        send(&msg);
    }
}

void telemetry_report_health(void)
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

void telemetry_report_boot(hal_reset_cause_t cause, params_result_t params_rc)
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
    if (signing_state() == SIGNING_KEY_CORRUPT) {
        link_send_statustext(MAV_SEVERITY_CRITICAL,
                             LINK_TEXT("signing: key record corrupt, all frames refused; re-provision"));
    }
    if ((calib_health() & CALIB_DEFAULTED) != 0u) {
        link_send_statustext(MAV_SEVERITY_WARNING, LINK_TEXT("calib: EEPROM tables bad or unfit, defaults in use"));
    }
    if (params_rc == PARAMS_CORRUPT) {
        link_send_statustext(MAV_SEVERITY_ERROR, LINK_TEXT("params: EEPROM record corrupt, defaults in use"));
    } else if (params_rc != PARAMS_OK) {
        link_send_statustext(MAV_SEVERITY_INFO, LINK_TEXT("params: no stored parameters, defaults in use"));
    }
}
