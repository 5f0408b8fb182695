/* The control task and the sonar tasks, see control.h. */
#include "control.h"

#include <string.h>

#include "calib.h"
#include "drive.h"
#include "encoder.h"
#include "hal.h"
#include "health.h"
#include "link.h"
#include "odometry.h"
#include "telemetry.h"
#include "wheels.h"

static behaviour_in_t s_in;   /* the sonar frame in it is written by control_sonar_frame_task */
static behaviour_out_t s_out;
static uint32_t s_out_ms; /* tick time of s_out */
static uint32_t s_frame_ms;
static bool s_watchdog_boot;
static bool s_params_corrupt; /* stored parameters were corrupt: defaults in use (health flag) */
static const sonar_ring_cfg_t *s_ring;
static bool s_frame_fault; /* a sensor of the frame in s_in.sonar is SONAR_FAULT (set with the frame) */
static bool s_raw_out;     /* the last tick drove the raw PWM outputs of a host setpoint unchanged */

void control_reset(bool watchdog_boot)
{
    s_watchdog_boot = watchdog_boot;
    memset(&s_in, 0, sizeof s_in);
    memset(&s_out, 0, sizeof s_out);
    s_frame_fault = false;
    s_raw_out = false;
    s_out_ms = 0u;
    s_frame_ms = hal_time_ms();
}

void control_init(const sonar_ring_cfg_t *ring, bool params_corrupt)
{
    s_ring = ring;
    s_params_corrupt = params_corrupt;
}

const behaviour_out_t *control_out(void) { return &s_out; }

uint32_t control_out_ms(void) { return s_out_ms; }

const sonar_frame_t *control_sonar_frame(void) { return s_ring != 0 ? &s_in.sonar : 0; }

uint32_t control_sonar_frame_ms(void) { return s_frame_ms; }

/* A fitted sensor that answered nothing leaves the robot blind on that side. */
static bool sonar_any_fault(const sonar_frame_t *f)
{
    for (uint8_t i = 0; i < f->count && i < SONAR_RING_MAX; i++) {
        if (f->status[i] == SONAR_FAULT) {
            return true;
        }
    }
    return false;
}

void control_sonar_task(void)
{
    if (s_ring == 0) {
        return;
    }
    sonar_ring_step(hal_time_us());
}

void control_sonar_frame_task(void)
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

void control_task(void)
{
    uint32_t now_ms = hal_time_ms();
    hal_watchdog_kick();
    uint16_t count_lo[ENCODER_MAX], edges_lo[ENCODER_MAX];
    wheels_update_odometry(s_out.steer_cdeg, count_lo, edges_lo);
    wheels_check_health(now_ms, !s_raw_out && s_out.speed_mm_s != 0, count_lo, edges_lo);
    telemetry_report_health();

    behaviour_in_t *in = &s_in;
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
    in->sonar_fault = s_ring != 0 && ((uint32_t)(now_ms - s_frame_ms) > CONTROL_SONAR_STALE_MS || s_frame_fault ||
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
