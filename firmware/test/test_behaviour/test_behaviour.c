/* Unity tests for lib/behaviour: arbitration order, failsafes and the hold after
 * them, passive motion safety timing, follow-wall canyon timers,
 * goal seek, integer trig.
 * behaviour is pure logic (no HAL calls): time is the input's now_ms. */
#include "unity.h"

#include "behaviour.h"
#include "params.h"
#include "sonar_ring.h"

#define TICK_MS 20u

static behaviour_in_t in;
static behaviour_out_t out;

static void frame_free(void)
{
    in.sonar.count = 12u;
    in.sonar.seq++;
    for (uint8_t i = 0; i < 12u; i++) {
        in.sonar.ranges_mm[i] = 4000u;
        in.sonar.status[i] = SONAR_NO_ECHO;
    }
}

static void set_range(uint8_t i, uint16_t mm)
{
    in.sonar.ranges_mm[i] = mm;
    in.sonar.status[i] = SONAR_VALID;
}

static void link_fresh(void)
{
    in.heartbeat_valid = true;
    in.heartbeat_rx_ms = in.now_ms;
}

/* A new host setpoint (what link_behaviour_inputs gives for one: its count and sequence number move on). */
static void host_cmd(int16_t steer, int16_t speed)
{
    in.host_valid = true;
    in.host_rx_ms = in.now_ms;
    in.host_steer_cdeg = steer;
    in.host_speed_mm_s = speed;
    in.host_gen++;
    in.host_seq++;
}

static void manual_cmd(int16_t steer, int16_t speed)
{
    in.manual_valid = true;
    in.manual_rx_ms = in.now_ms;
    in.manual_steer_cdeg = steer;
    in.manual_speed_mm_s = speed;
    in.manual_gen++;
}

static void goal_cmd(int32_t x_mm, int32_t y_mm)
{
    in.goal_active = true;
    in.goal_x_mm = x_mm;
    in.goal_y_mm = y_mm;
    in.goal_gen++;
}

/* MAV_CMD_AGNAV_SET_BEHAVIOURS */
static void modes(uint8_t flags)
{
    in.mode_flags = flags;
    in.mode_gen++;
}

static void tick(void) { behaviour_step(&in, &out); }

/* The behaviour group alone: params_init() writes its rows' defaults into behaviour_params. */
static const PARAMS_ROM param_group_ref_t GROUPS[] = {&BEHAVIOUR_PARAM_GROUP};

static void reinit(void)
{
    params_init(GROUPS, 1u);
    behaviour_init(&behaviour_params, &SONAR_RING_12_SDLG);
}

void setUp(void)
{
    uint8_t *z = (uint8_t *)&in;
    for (uint16_t k = 0; k < sizeof in; k++) {
        z[k] = 0u;
    }
    in.now_ms = 1000u;
    frame_free();
    link_fresh();
    in.mode_flags = BHV_MODE_AVOID; /* link's default */
    reinit();
}

void tearDown(void) {}

/* ---- arbitration -------------------------------------------------------- */

void test_behaviour_step_highest_layer_wins_when_several_layers_command(void)
{
    /* every layer has something to do */
    in.estop = true;
    set_range(0, 200u);                       /* obstacle dead ahead */
    set_range(1, 500u);                       /* wall front-left */
    set_range(2, 500u);
    manual_cmd(1111, 222);
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_GOAL_SEEK | BHV_MODE_AVOID);
    host_cmd(-500, 333);
    goal_cmd(5000, 0);

    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_FAILSAFE, out.layer, "estop beats all");
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_ESTOP, out.reason);
    TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);

    in.estop = false;
    reinit();
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_AVOID_OBSTACLE, out.layer, "avoid beats manual");
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_OBSTACLE_STOP, out.reason);
    TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);

    set_range(0, 2500u);
    reinit();
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_MANUAL, out.layer, "manual beats follow wall");
    TEST_ASSERT_EQUAL_INT16(1111, out.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(222, out.speed_mm_s);

    in.manual_valid = false;
    reinit();
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_FOLLOW_WALL, out.layer, "follow wall beats host");
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_WALL_LEFT, out.reason);
    TEST_ASSERT_TRUE_MESSAGE(out.steer_cdeg < 0, "turns right, away from the left wall");

    in.mode_flags = BHV_MODE_GOAL_SEEK | BHV_MODE_AVOID;
    reinit();
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "host beats goal");
    TEST_ASSERT_EQUAL_INT16(-500, out.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(333, out.speed_mm_s);

    in.host_valid = false;
    reinit();
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_MOVE_TO_GOAL, out.layer, "goal when alone");
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_GOAL_SEEK, out.reason);

    in.goal_active = false;
    reinit();
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "nobody commands");
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_NO_COMMAND, out.reason);
    TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);
}

void test_behaviour_host_command_is_limited_to_max_speed_and_steer(void)
{
    host_cmd(9000, -3000);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    TEST_ASSERT_EQUAL_INT16(behaviour_params.max_steer_cdeg, out.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(-behaviour_params.max_speed_mm_s, out.speed_mm_s);
}

void test_behaviour_manual_override_expires_after_manual_timeout(void)
{
    host_cmd(0, 300);
    manual_cmd(0, -150);
    uint32_t t0 = in.now_ms;
    for (uint8_t k = 0; k < 30u; k++) {
        link_fresh();
        host_cmd(0, 300);
        tick();
        uint32_t age = in.now_ms - t0;
        if (age <= behaviour_params.manual_timeout_ms) {
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_MANUAL, out.layer, "fresh override commands");
            TEST_ASSERT_EQUAL_INT16(-150, out.speed_mm_s);
        } else {
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "stale override ignored");
        }
        in.now_ms += TICK_MS;
    }
}

/* ---- failsafes ------------------------------------------------------------ */

void test_behaviour_link_loss_stops_by_timeout_plus_one_tick_not_before(void)
{
    in.now_ms = 1003u;
    link_fresh();
    host_cmd(0, 500);
    uint32_t t_last_rx = in.now_ms;
    uint32_t t_stop = 0u;
    for (uint8_t k = 0; k < 60u; k++) {
        tick();
        uint32_t age = in.now_ms - t_last_rx;
        if (age <= behaviour_params.link_timeout_ms) {
            TEST_ASSERT_EQUAL_INT16_MESSAGE(500, out.speed_mm_s, "stopped before the link timeout");
        } else if (t_stop == 0u) {
            t_stop = in.now_ms;
        }
        if (age >= behaviour_params.link_timeout_ms + TICK_MS) {
            TEST_ASSERT_EQUAL_INT16_MESSAGE(0, out.speed_mm_s, "still moving after timeout + one tick");
            TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_FAILSAFE, out.layer);
            TEST_ASSERT_EQUAL_UINT8(BHV_REASON_LINK_LOSS, out.reason);
            TEST_ASSERT_BITS_HIGH(BHV_FS_LINK_LOSS, out.failsafe_flags);
        }
        in.now_ms += TICK_MS;
    }
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(TICK_MS / 2u, t_last_rx + behaviour_params.link_timeout_ms + TICK_MS / 2u,
                                      t_stop, "first stopped tick");
    /* link back: host command resumes without arming */
    link_fresh();
    host_cmd(0, 200);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    TEST_ASSERT_EQUAL_INT16(200, out.speed_mm_s);
}

void test_behaviour_new_params_apply_at_once_and_keep_the_latches(void)
{
    in.estop = true;
    tick(); /* latched */
    in.estop = false;
    behaviour_params_t p = behaviour_params;
    p.max_speed_mm_s = 150;
    p.link_timeout_ms = 2000u;
    behaviour_set_params(&p);
    in.now_ms += TICK_MS;
    host_cmd(0, 400);
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_REASON_ESTOP, out.reason, "new parameters released the e-stop latch");
    behaviour_arm();
    in.now_ms += TICK_MS;
    host_cmd(0, 400);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    TEST_ASSERT_EQUAL_INT16_MESSAGE(150, out.speed_mm_s, "new MAX_SPEED_MM_S not applied");
    /* the new link timeout: 1 s without anything is no link loss any more */
    in.heartbeat_valid = false;
    in.now_ms += 1000u;
    host_cmd(0, 400);
    in.host_rx_ms = in.now_ms - 1000u;
    in.host_valid = true;
    in.heartbeat_rx_ms = in.now_ms - 1000u;
    tick();
    TEST_ASSERT_FALSE_MESSAGE((out.failsafe_flags & BHV_FS_LINK_LOSS) != 0u, "old 500 ms link timeout still in force");
}

void test_behaviour_estop_stays_latched_until_armed(void)
{
    in.estop = true;
    for (uint8_t k = 0; k < 100u; k++) {
        if (k == 10u) {
            in.estop = false; /* released, but latched */
        }
        if (k == 50u) {
            behaviour_arm(); /* ...only after the release; still fine */
        }
        if (k == 5u) {
            behaviour_arm(); /* arm while the e-stop is still pressed: no effect */
        }
        link_fresh();
        host_cmd(0, 400);
        tick();
        if (k < 50u) {
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_FAILSAFE, out.layer, "e-stop not latched");
            TEST_ASSERT_EQUAL_UINT8(BHV_REASON_ESTOP, out.reason);
            TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);
            TEST_ASSERT_BITS_HIGH(BHV_FS_ESTOP, out.failsafe_flags);
        } else {
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "arm did not clear");
            TEST_ASSERT_EQUAL_INT16(400, out.speed_mm_s);
        }
        in.now_ms += TICK_MS;
    }
}

void test_behaviour_watchdog_boot_stays_stopped_until_armed(void)
{
    in.reset_was_watchdog = true; /* main passes the boot reset cause every tick */
    for (uint16_t k = 0; k < 200u; k++) {
        if (k == 150u) {
            behaviour_arm();
        }
        link_fresh();
        host_cmd(100, 400);
        tick();
        if (k < 150u) {
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_FAILSAFE, out.layer, "moved before arm");
            TEST_ASSERT_EQUAL_UINT8(BHV_REASON_WATCHDOG_BOOT, out.reason);
            TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);
            TEST_ASSERT_BITS_HIGH(BHV_FS_WATCHDOG_RESET, out.failsafe_flags);
        } else {
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "re-latched on a level");
            TEST_ASSERT_BITS_LOW(BHV_FS_WATCHDOG_RESET, out.failsafe_flags);
        }
        in.now_ms += TICK_MS;
    }
}

void test_behaviour_sensor_fault_stops_but_calib_defaulted_only_flags(void)
{
    host_cmd(0, 400);
    in.calib_defaulted = true;
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "calib flag must not stop");
    TEST_ASSERT_BITS_HIGH(BHV_FS_CALIB_DEFAULTED, out.failsafe_flags);
    in.encoder_fault = true;
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_FAILSAFE, out.layer);
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_SENSOR_FAULT, out.reason);
    TEST_ASSERT_EQUAL_HEX8(BHV_FS_ENCODER_FAULT | BHV_FS_CALIB_DEFAULTED, out.failsafe_flags);
    in.encoder_fault = false;
    in.sonar_fault = true;
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_SENSOR_FAULT, out.reason);
    TEST_ASSERT_BITS_HIGH(BHV_FS_SONAR_FAULT, out.failsafe_flags);
    in.sonar_fault = false;
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "the setpoint from before the fault resumed");
    host_cmd(0, 400);
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "fault cleared: the next setpoint drives");
}

/* ---- the hold after a failsafe: motion again only on a fresh command ------ */

static void ticks(uint16_t n, bool heartbeats)
{
    for (uint16_t k = 0; k < n; k++) {
        if (heartbeats) {
            link_fresh();
        }
        tick();
        in.now_ms += TICK_MS;
    }
}

/* A goal being sought, the host gone (link loss), then a ground station's heartbeats: nothing moves
 * until a new goal arrives. */
void test_behaviour_heartbeats_after_link_loss_do_not_resume_a_stored_goal(void)
{
    modes(BHV_MODE_GOAL_SEEK | BHV_MODE_AVOID);
    goal_cmd(8000, 0);
    ticks(10u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MOVE_TO_GOAL, out.layer);
    ticks(40u, false); /* 800 ms of silence */
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_LINK_LOSS, out.reason);
    for (uint16_t k = 0; k < 150u; k++) { /* 3 s of heartbeats */
        link_fresh();
        tick();
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "a heartbeat restarted the stored goal");
        TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);
        in.now_ms += TICK_MS;
    }
    goal_cmd(8000, 0); /* the host sends its goal again */
    ticks(1u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MOVE_TO_GOAL, out.layer);
    TEST_ASSERT_TRUE(out.speed_mm_s > 0);
}

/* The setpoint from before each kind of failsafe is still younger than HOST_TIMEOUT_MS when the
 * failsafe ends: it is not obeyed; the next setpoint is. */
void test_behaviour_setpoint_from_before_any_failsafe_is_not_obeyed_after_it(void)
{
    behaviour_params_t p = behaviour_params;
    p.host_timeout_ms = 5000u;
    behaviour_set_params(&p);
    for (uint8_t kind = 0; kind < 4u; kind++) {
        host_cmd(0, 400);
        ticks(2u, true);
        TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
        if (kind == 0u) {
            ticks(30u, false); /* link loss */
        } else if (kind == 1u) {
            in.estop = true; /* e-stop, released and armed */
            ticks(5u, true);
            in.estop = false;
            behaviour_arm();
        } else if (kind == 2u) {
            in.sonar_fault = true; /* a sensor fault that clears */
            ticks(5u, true);
            in.sonar_fault = false;
        } else {
            in.reset_was_watchdog = true; /* a watchdog boot, then the host's arm */
            ticks(5u, true);
            behaviour_arm();
        }
        ticks(50u, true);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "a stale setpoint drives after the failsafe");
        TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);
        host_cmd(0, 300);
        ticks(1u, true);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "a new setpoint after the failsafe");
        TEST_ASSERT_EQUAL_INT16(300, out.speed_mm_s);
    }
}

/* A setpoint taken after the failsafe whose sequence number is not newer than the last one before
 * it is a replay: held. An arm starts a new host session, whose numbers start again. */
void test_behaviour_replayed_setpoint_is_held_until_a_newer_one_or_an_arm(void)
{
    host_cmd(0, 400);
    in.host_seq = 500u;
    ticks(2u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    ticks(30u, false); /* link loss */
    for (uint16_t seq = 480u; seq <= 500u; seq++) { /* the captured frames again */
        host_cmd(0, 400);
        in.host_seq = seq;
        ticks(1u, true);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "a replayed setpoint drives");
    }
    host_cmd(0, 250);
    in.host_seq = 501u;
    ticks(1u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    TEST_ASSERT_EQUAL_INT16(250, out.speed_mm_s);

    ticks(30u, false); /* link loss; the host restarts: arm, then its setpoints from 1 */
    behaviour_arm();
    host_cmd(0, 200);
    in.host_seq = 1u;
    ticks(1u, true);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "a new session after an arm");
    TEST_ASSERT_EQUAL_INT16(200, out.speed_mm_s);

    behaviour_arm(); /* an arm while driving does not make a later replay new */
    host_cmd(0, 200);
    in.host_seq = 2u;
    ticks(2u, true);
    ticks(30u, false);
    host_cmd(0, 200);
    in.host_seq = 2u;
    ticks(5u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_IDLE, out.layer);
}

/* Manual override from before a failsafe is held as well; a new one is obeyed. */
void test_behaviour_manual_override_from_before_a_failsafe_is_held(void)
{
    behaviour_params_t p = behaviour_params;
    p.manual_timeout_ms = 5000u;
    behaviour_set_params(&p);
    manual_cmd(0, 300);
    ticks(2u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MANUAL, out.layer);
    in.estop = true;
    ticks(3u, true);
    in.estop = false;
    behaviour_arm();
    ticks(10u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_IDLE, out.layer);
    manual_cmd(0, 300);
    ticks(1u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MANUAL, out.layer);
}

/* Follow-wall needs no command while it runs, so after a failsafe it waits for one: an arm, a
 * SET_BEHAVIOURS or any new command. Heartbeats alone do not release it. */
void test_behaviour_follow_wall_waits_for_a_command_after_a_failsafe(void)
{
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_AVOID);
    set_range(10, 400u); /* wall front-right */
    set_range(11, 600u);
    ticks(2u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_FOLLOW_WALL, out.layer);
    ticks(30u, false);
    ticks(100u, true);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "heartbeats restarted follow-wall");
    behaviour_arm();
    ticks(1u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_FOLLOW_WALL, out.layer);
    ticks(30u, false);
    ticks(5u, true);
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_IDLE, out.layer);
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_AVOID);
    ticks(1u, true);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_FOLLOW_WALL, out.layer, "SET_BEHAVIOURS releases it");
}

/* Still rolling towards an obstacle when the link comes back with heartbeats only: the avoid layer
 * does not start its back-off (motion nobody commanded). */
void test_behaviour_no_back_off_without_a_command_after_a_failsafe(void)
{
    host_cmd(0, 400);
    ticks(2u, true);
    ticks(30u, false);
    in.speed_mm_s = 200; /* coasting */
    set_range(0, 200u);
    for (uint16_t k = 0; k < 100u; k++) {
        link_fresh();
        tick();
        TEST_ASSERT_TRUE_MESSAGE(out.speed_mm_s == 0, "moved without a command");
        in.speed_mm_s = in.speed_mm_s > 10 ? (int16_t)(in.speed_mm_s - 10) : 0;
        in.now_ms += TICK_MS;
    }
}

/* ---- avoid obstacle (passive motion safety) ----------------------------- */

/* Plant: the measured speed is last tick's command. Returns the time of the
 * first tick whose reason is `reason` (0 if none) within max_ticks. */
static uint32_t run_until_reason(uint8_t reason, uint16_t max_ticks)
{
    for (uint16_t k = 0; k < max_ticks; k++) {
        link_fresh();
        host_cmd(0, 400);
        tick();
        in.speed_mm_s = out.speed_mm_s;
        uint32_t t = in.now_ms;
        in.now_ms += TICK_MS;
        if (out.reason == reason) {
            return t;
        }
    }
    return 0u;
}

void test_behaviour_avoid_runs_stop_backoff_wait_release_with_timings(void)
{
    const behaviour_params_t *p = &behaviour_params;
    in.speed_mm_s = 400;
    set_range(11, 250u); /* person front-right, inside the cone and the 300 mm limit */
    uint32_t t0 = run_until_reason(BHV_REASON_OBSTACLE_STOP, 5u);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(1000u, t0, "stop on the first tick");
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_AVOID_OBSTACLE, out.layer);
    TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);

    uint32_t t_back = run_until_reason(BHV_REASON_OBSTACLE_BACKOFF, 100u);
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(TICK_MS, t0 + p->avoid_stop_ms, t_back, "stop phase length");
    TEST_ASSERT_EQUAL_INT16(-p->avoid_backoff_speed_mm_s, out.speed_mm_s);

    uint32_t t_wait = run_until_reason(BHV_REASON_OBSTACLE_WAIT, 200u);
    uint32_t backoff_ms = (uint32_t)p->avoid_backoff_mm * 1000u / (uint32_t)p->avoid_backoff_speed_mm_s;
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(2u * TICK_MS, t_back + backoff_ms, t_wait, "back-off covers 50 mm");
    TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);

    set_range(11, 4000u); /* the person walks away */
    uint32_t t_rel = run_until_reason(BHV_REASON_HOST_SETPOINT, 200u);
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(TICK_MS, t_wait + p->avoid_wait_ms, t_rel, "wait length");
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    TEST_ASSERT_EQUAL_INT16(400, out.speed_mm_s);
}

void test_behaviour_avoid_repeats_cycle_when_obstacle_stays(void)
{
    in.speed_mm_s = 400;
    set_range(0, 200u);
    uint32_t t0 = run_until_reason(BHV_REASON_OBSTACLE_STOP, 5u);
    uint32_t t_wait = run_until_reason(BHV_REASON_OBSTACLE_WAIT, 200u);
    TEST_ASSERT_TRUE(t_wait > t0);
    uint32_t t_again = run_until_reason(BHV_REASON_OBSTACLE_STOP, 200u);
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(TICK_MS, t_wait + behaviour_params.avoid_wait_ms, t_again,
                                      "blocked path: stop again right after the wait");
}

void test_behaviour_avoid_ignores_obstacle_when_not_moving_forward(void)
{
    set_range(0, 150u);
    in.speed_mm_s = -100;
    host_cmd(0, -100); /* reversing away */
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
    TEST_ASSERT_EQUAL_INT16(-100, out.speed_mm_s);
    set_range(0, 4000u);
    set_range(6, 150u); /* obstacle behind, driving forward: not the front cone */
    host_cmd(0, 300);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_HOST_COMMAND, out.layer);
}

void test_behaviour_avoid_abstains_when_mode_flag_clear(void)
{
    in.mode_flags = 0u;
    in.speed_mm_s = 300;
    set_range(0, 150u);
    host_cmd(0, 300);
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_HOST_COMMAND, out.layer, "avoid disabled by the host");
    in.mode_flags = BHV_MODE_AVOID;
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_AVOID_OBSTACLE, out.layer);
}

/* ---- move to goal -------------------------------------------------------- */

void test_behaviour_goal_seek_steers_toward_goal_and_stops_within_tolerance(void)
{
    modes(BHV_MODE_GOAL_SEEK | BHV_MODE_AVOID);
    goal_cmd(3000, 0);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MOVE_TO_GOAL, out.layer);
    TEST_ASSERT_INT16_WITHIN(20, 0, out.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(behaviour_params.goal_speed_mm_s, out.speed_mm_s);

    in.goal_x_mm = 1000; /* 45 deg to the right, 1.41 m */
    in.goal_y_mm = -1000;
    tick();
    TEST_ASSERT_INT16_WITHIN_MESSAGE(20, -3000, out.steer_cdeg, "clamped right turn");

    in.heading_cdeg = -4000; /* nearly facing it: steer = bearing error (-5 deg) */
    tick();
    TEST_ASSERT_INT16_WITHIN(20, -500, out.steer_cdeg);

    in.x_mm = 500; /* 707 mm left: slowed down */
    in.y_mm = -500;
    in.heading_cdeg = -4500;
    tick();
    TEST_ASSERT_INT16_WITHIN(10, 283, out.speed_mm_s);

    in.x_mm = 950;
    in.y_mm = -960;
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_GOAL_REACHED, out.reason);
    TEST_ASSERT_EQUAL_INT16(0, out.speed_mm_s);
}

/* ---- follow wall and the canyon effect ---------------------------------- */

void test_behaviour_wall_steers_away_from_nearer_side(void)
{
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_AVOID);
    set_range(10, 400u); /* wall front-right */
    set_range(11, 600u);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_FOLLOW_WALL, out.layer);
    TEST_ASSERT_EQUAL_UINT8(BHV_REASON_WALL_RIGHT, out.reason);
    TEST_ASSERT_TRUE_MESSAGE(out.steer_cdeg > 0, "turn left, away from the right wall");
    TEST_ASSERT_TRUE(out.speed_mm_s > 0 && out.speed_mm_s < behaviour_params.wall_speed_mm_s);
    uint32_t l, r;
    behaviour_wall_extents(&l, &r);
    TEST_ASSERT_TRUE(r > l);
    set_range(10, 4000u);
    set_range(11, 4000u);
    in.sonar.status[10] = SONAR_NO_ECHO;
    in.sonar.status[11] = SONAR_NO_ECHO;
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "open space: layer abstains");
}

/* Exit test (ref 002 eq. 8) with a post beside the robot on the goal's side, where the front-side
 * sensors do not look: move-to-goal would turn into it, so the wall layer keeps the robot (turning
 * away) while that side has an echo closer than avoid_stop (300 mm). */
void test_behaviour_wall_does_not_hand_over_towards_a_near_post_on_the_goals_side(void)
{
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_GOAL_SEEK | BHV_MODE_AVOID);
    goal_cmd(3000, 1500); /* 27 deg to the left */
    set_range(2, 60u); /* a post 6 cm off, 60 deg left */
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_FOLLOW_WALL, out.layer);
    TEST_ASSERT_TRUE_MESSAGE(out.steer_cdeg < 0, "turns right, away from the post");
    in.goal_y_mm = -1500; /* the goal on the other side: handed over as before */
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MOVE_TO_GOAL, out.layer);
    in.goal_y_mm = 1500; /* the post 1 m off: handed over towards it */
    set_range(2, 1000u);
    tick();
    TEST_ASSERT_EQUAL_UINT8(BHV_LAYER_MOVE_TO_GOAL, out.layer);
}

/* The sums worked out ahead by behaviour_sonar_frame() (main's sonar task) give the same
 * output as the tick working them out itself; a frame with a new seq is not served stale sums. */
void test_behaviour_wall_precomputed_frame_matches_tick(void)
{
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_AVOID);
    set_range(10, 400u);
    set_range(11, 600u);
    set_range(1, 900u);
    tick();
    behaviour_out_t ref = out;
    uint32_t l0, r0;
    behaviour_wall_extents(&l0, &r0);

    reinit();
    behaviour_sonar_frame(&in.sonar);
    tick();
    uint32_t l1, r1;
    behaviour_wall_extents(&l1, &r1);
    TEST_ASSERT_EQUAL_UINT32(l0, l1);
    TEST_ASSERT_EQUAL_UINT32(r0, r1);
    TEST_ASSERT_EQUAL_INT16(ref.steer_cdeg, out.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(ref.speed_mm_s, out.speed_mm_s);
    TEST_ASSERT_EQUAL_UINT8(ref.reason, out.reason);

    frame_free(); /* new seq, not handed to behaviour_sonar_frame: the tick computes */
    tick();
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_IDLE, out.layer, "stale sums of the previous frame not used");
}

/* Dead end, robot at the origin: side walls at y = +-400 mm, end wall at
 * x = 1000 mm, open behind. Range along world angle a (cdeg) by integer
 * ray casting, capped at the 4 m sensor range. */
#define CANYON_W_MM 400L
#define CANYON_D_MM 1000L

static uint16_t canyon_ray_mm(int32_t a_cdeg)
{
    int32_t c = behaviour_cos_q14(a_cdeg);
    int32_t s = behaviour_sin_q14(a_cdeg);
    int32_t best = 4000L;
    if (s != 0) {
        int32_t t = (CANYON_W_MM * 16384L) / (s > 0 ? s : -s);
        if (t < best) {
            best = t;
        }
    }
    if (c > 0) {
        int32_t t = (CANYON_D_MM * 16384L) / c;
        if (t < best) {
            best = t;
        }
    }
    return (uint16_t)best;
}

/* 20 s of follow-wall in the dead end; the robot turns in place with a yaw
 * rate of 3 x steer per second (2000 cdeg steer -> 60 deg/s), the ring
 * refreshes every 5 ticks (10 Hz). Returns the number of steering sign
 * changes; *heading gets the final heading. */
static uint16_t canyon_run(uint16_t canyon_ms, int32_t *heading)
{
    behaviour_params_t p = behaviour_params;
    p.wall_canyon_ms = canyon_ms;
    behaviour_init(&p, &SONAR_RING_12_SDLG);
    modes(BHV_MODE_FOLLOW_WALL | BHV_MODE_AVOID);
    int32_t h = 0;
    int8_t last_sign = 0;
    uint16_t changes = 0u;
    for (uint16_t k = 0; k < 1000u; k++) {
        if (k % 5u == 0u) {
            in.sonar.seq++;
            for (uint8_t i = 0; i < 12u; i++) {
                uint16_t rng = canyon_ray_mm(h + SONAR_RING_12_SDLG.sensor[i].bearing_cdeg);
                in.sonar.ranges_mm[i] = rng;
                in.sonar.status[i] = rng >= 4000u ? SONAR_NO_ECHO : SONAR_VALID;
            }
        }
        link_fresh();
        tick();
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(BHV_LAYER_FOLLOW_WALL, out.layer, "wall layer in charge");
        /* (int32_t)TICK_MS: with a 32-bit long, long * unsigned int is unsigned long. */
        h = behaviour_wrap_cdeg(h + ((int32_t)out.steer_cdeg * 3L * (int32_t)TICK_MS) / 1000L);
        int8_t sign = out.steer_cdeg > 0 ? 1 : (out.steer_cdeg < 0 ? -1 : 0);
        if (sign != 0) {
            if (last_sign != 0 && sign != last_sign) {
                changes++;
            }
            last_sign = sign;
        }
        in.now_ms += TICK_MS;
    }
    *heading = h;
    return changes;
}

void test_behaviour_canyon_timers_bound_left_right_switching_in_dead_end(void)
{
    int32_t h = 0;
    uint16_t changes = canyon_run(behaviour_params.wall_canyon_ms, &h);
    /* At most one switch per canyon period would already be bounded (13 in
     * 20 s); the committed turn actually escapes with (almost) none. */
    TEST_ASSERT_TRUE_MESSAGE(changes <= 3u, "left-right switching not bounded");
    TEST_ASSERT_TRUE_MESSAGE(h >= 15000L || h <= -15000L, "robot did not turn to face the way out");
}

void test_behaviour_canyon_without_timers_oscillates(void)
{
    int32_t h = 0;
    uint16_t changes = canyon_run(0u, &h);
    TEST_ASSERT_TRUE_MESSAGE(changes >= 50u, "expected endless left-right switching without timers");
    TEST_ASSERT_TRUE_MESSAGE(h < 3000L && h > -3000L, "stuck facing the dead end");
}

/* ---- integer trig ---------------------------------------------------------- */

void test_behaviour_integer_trig_within_tolerance(void)
{
    TEST_ASSERT_EQUAL_INT16(16384, behaviour_cos_q14(0));
    TEST_ASSERT_INT16_WITHIN(3, 14189, behaviour_cos_q14(3000));      /* cos 30 */
    TEST_ASSERT_INT16_WITHIN(16, 8192, behaviour_cos_q14(-6000));     /* cos -60 */
    TEST_ASSERT_INT16_WITHIN(3, -16384, behaviour_cos_q14(18000));
    TEST_ASSERT_INT16_WITHIN(16, 11878, behaviour_cos_q14(4350));     /* interpolated 43.5 deg */
    TEST_ASSERT_INT16_WITHIN(3, 16384, behaviour_sin_q14(9000));
    TEST_ASSERT_INT16_WITHIN(3, -8192, behaviour_sin_q14(-3000));
    TEST_ASSERT_INT16_WITHIN(5, 4500, behaviour_atan2_cdeg(1000, 1000));
    TEST_ASSERT_INT16_WITHIN(5, -13500, behaviour_atan2_cdeg(-7, -7));
    TEST_ASSERT_INT16_WITHIN(5, 9000, behaviour_atan2_cdeg(50000000L, 0));
    TEST_ASSERT_INT16_WITHIN(5, 1909, behaviour_atan2_cdeg(346, 1000));  /* 19.09 deg */
    TEST_ASSERT_INT16_WITHIN(5, 16091, behaviour_atan2_cdeg(346, -1000));
    TEST_ASSERT_EQUAL_INT32(-17000L, behaviour_wrap_cdeg(19000L));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_behaviour_step_highest_layer_wins_when_several_layers_command);
    RUN_TEST(test_behaviour_host_command_is_limited_to_max_speed_and_steer);
    RUN_TEST(test_behaviour_new_params_apply_at_once_and_keep_the_latches);
    RUN_TEST(test_behaviour_manual_override_expires_after_manual_timeout);
    RUN_TEST(test_behaviour_link_loss_stops_by_timeout_plus_one_tick_not_before);
    RUN_TEST(test_behaviour_estop_stays_latched_until_armed);
    RUN_TEST(test_behaviour_watchdog_boot_stays_stopped_until_armed);
    RUN_TEST(test_behaviour_sensor_fault_stops_but_calib_defaulted_only_flags);
    RUN_TEST(test_behaviour_heartbeats_after_link_loss_do_not_resume_a_stored_goal);
    RUN_TEST(test_behaviour_setpoint_from_before_any_failsafe_is_not_obeyed_after_it);
    RUN_TEST(test_behaviour_replayed_setpoint_is_held_until_a_newer_one_or_an_arm);
    RUN_TEST(test_behaviour_manual_override_from_before_a_failsafe_is_held);
    RUN_TEST(test_behaviour_follow_wall_waits_for_a_command_after_a_failsafe);
    RUN_TEST(test_behaviour_no_back_off_without_a_command_after_a_failsafe);
    RUN_TEST(test_behaviour_avoid_runs_stop_backoff_wait_release_with_timings);
    RUN_TEST(test_behaviour_avoid_repeats_cycle_when_obstacle_stays);
    RUN_TEST(test_behaviour_avoid_ignores_obstacle_when_not_moving_forward);
    RUN_TEST(test_behaviour_avoid_abstains_when_mode_flag_clear);
    RUN_TEST(test_behaviour_goal_seek_steers_toward_goal_and_stops_within_tolerance);
    RUN_TEST(test_behaviour_wall_steers_away_from_nearer_side);
    RUN_TEST(test_behaviour_wall_does_not_hand_over_towards_a_near_post_on_the_goals_side);
    RUN_TEST(test_behaviour_wall_precomputed_frame_matches_tick);
    RUN_TEST(test_behaviour_canyon_timers_bound_left_right_switching_in_dead_end);
    RUN_TEST(test_behaviour_canyon_without_timers_oscillates);
    RUN_TEST(test_behaviour_integer_trig_within_tolerance);
    return UNITY_END();
}
