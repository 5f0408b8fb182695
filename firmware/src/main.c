/*
 * AgNav robot controller: wiring and the static scheduler table only.
 *
 * Every module lives in firmware/lib/<module>; this file connects them:
 *   link (MAVLink in) -> behaviour inputs; encoders -> odometry (wheels); sonar ring ->
 *   behaviour; behaviour out -> drive (calibration tables -> PWM) (control); telemetry out;
 *   calibration messages (calib_service); the records lib/storage writes (storage_records).
 * EEPROM map: see storage.h (signing key, calibration record, then parameters).
 */
#include "behaviour.h"
#include "calib.h"
#include "calib_service.h"
#include "control.h"
#include "drive.h"
#include "encoder.h"
#include "hal.h"
#include "health.h"
#include "link.h"
#include "odometry.h"
#include "params.h"
#include "sched.h"
#include "signing.h"
#include "sonar_ring.h"
#include "storage.h"
#include "storage_records.h"
#include "telemetry.h"

#define WATCHDOG_TIMEOUT_MS 250u
#define KEY_PROVISION_WINDOW_MS 10000u /* unsigned SETUP_SIGNING accepted this long after a power-on */

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
        calib_service_storage_done(done, failed);
    }
    apply_params();
    link_state_t *ls = link_state();
    if (ls->arm_request) {
        ls->arm_request = false;
        behaviour_arm();
        health_clear(); /* a sensor still faulty latches again (docs/safety.md) */
    }
}

/* The static scheduler table: {task, period ms, budget us, name}. */
#define TASK_COUNT 6u
#define TASK_CONTROL 2u /* row of the control task */
static const sched_task_t TASKS[TASK_COUNT] = {
    {task_link, 2u, 600u, "link"},
    {control_sonar_task, 1u, 350u, "sonar"}, /* worst 320 us measured, interrupts included */
    {control_task, 20u, 1000u, "control"},
    {control_sonar_frame_task, 1u, 300u, "sonframe"}, /* after the control task: never delays a tick */
    {telemetry_task_50hz, 20u, 300u, "telem50"},     /* BEHAVIOUR_STATUS, right after the tick */
    {telemetry_task, 20u, 800u, "telem"},
};
_Static_assert(sizeof TASKS / sizeof TASKS[0] == TASK_COUNT, "TASK_COUNT matches the table");
static sched_stats_t s_stats[TASK_COUNT];

void agnav_setup(void)
{
    hal_init();
    /* A reset the robot did not ask for (watchdog: a hung loop; brown-out: the supply sagged,
     * e.g. motors stalling a weak battery) may have come in mid-motion: boot stopped, and stay
     * stopped until the host arms again (behaviour's watchdog-boot latch). */
    hal_reset_cause_t cause = hal_reset_cause();
    /* A reset is a fresh start (the native SIL re-enters agnav_setup() without reloading the program). */
    control_reset(cause == HAL_RESET_WATCHDOG || cause == HAL_RESET_BROWN_OUT);
    telemetry_reset();
    params_init(PARAM_GROUPS, PARAM_GROUP_COUNT);
    storage_init();
    params_result_t params_rc = params_load();

    calib_init();
    calib_load();
    calib_service_drop_unfit();

    encoder_init_params(&encoder_params);
    odom_cfg_t oc = {drive_params.kind == DRIVE_DIFFERENTIAL ? ODOM_MODEL_DIFF : ODOM_MODEL_ACKERMANN,
                     drive_params.track_mm, odom_param_wheelbase_mm};
    odom_init(&oc);
    const sonar_ring_cfg_t *ring = sonar_ring_for_count(sonar_ring_param_count);
    if (ring != 0) {
        sonar_ring_init(ring);
    }
    behaviour_init(&behaviour_params, ring);
    health_init(&health_params, encoder_params.count);
    s_param_changes = params_changes();
    drive_init(&drive_params);
    control_init(ring, params_rc == PARAMS_CORRUPT);

    /* The signing key may be provisioned unsigned only right after a power-on or external
     * reset: on the Mega, opening the USB serial port resets the board (DTR auto-reset), so
     * this is "someone at the robot with a cable". Watchdog / brown-out boots: no window. */
    uint16_t window_ms = (cause == HAL_RESET_POWER_ON || cause == HAL_RESET_EXTERNAL) ? KEY_PROVISION_WINDOW_MS : 0u;
    link_cfg_t lc = {link_param_sysid,
                     MAV_COMP_ID_AUTOPILOT1,
                     behaviour_params.max_steer_cdeg,
                     behaviour_params.max_speed_mm_s,
                     calib_service_on_msg,
                     window_ms,
                     &s_stats[TASK_CONTROL].next_due_us};
    hal_uart_init(HAL_UART_LINK, 57600u);
    link_init(&lc);
    signing_set_sign_telemetry(signing_param_sign_telem != 0u); /* before the boot report goes out */
    link_state()->behaviour_enable = behaviour_boot_modes;
    telemetry_report_boot(cause, params_rc);
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
