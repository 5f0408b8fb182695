/* Bad commands: every class of bad input is refused (or clamped), answered and counted; only a
 * command taken counts as a new one. */
#include <math.h>
#include <string.h>
#include <unity.h>

#include "hal.h"
#include "link.h"
#include "link_wire.h"
#include "params.h"
#include "sim/hal_sim.h"

#define HOST_SYS 255u
#define HOST_COMP 190u
#define US 1u /* our system id */

static uint16_t s_timeout_ms;
static const PARAMS_ROM param_def_t TABLE[] = {
    {"LINK_TIMEOUT_MS", 0, PARAM_U16, &s_timeout_ms, 100, 5000, 500},
};
static const PARAMS_ROM param_group_t GROUP = PARAM_GROUP(TABLE);
static const PARAMS_ROM param_group_ref_t GROUPS[] = {&GROUP};

static mavlink_message_t s_msg;

static void send_to_robot(const mavlink_message_t *msg)
{
    wire_send(msg);
    link_poll(100u);
}

/* Frames of msgid the robot sent (drained), the last one in s_msg. */
static uint8_t robot_sent(uint32_t msgid) { return wire_take(msgid, &s_msg); }

void setUp(void)
{
    sim_reset();
    params_init(GROUPS, 1u); /* LINK_TIMEOUT_MS 500 */
    link_cfg_t cfg = {US, 1u, 2460, 2000, 0, 0u, 0};
    link_init(&cfg);
}

void tearDown(void) {}

static void command(uint8_t target, uint16_t cmd, float p1, float p2, float p3)
{
    mavlink_msg_command_long_pack(HOST_SYS, HOST_COMP, &s_msg, target, 1, cmd, 0, p1, p2, p3, 0, 0, 0, 0);
    send_to_robot(&s_msg);
}

/* The single COMMAND_ACK the robot sent: result and result_param2 (reason). */
static void expect_ack(uint16_t cmd, uint8_t result, int32_t reason)
{
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(1u, robot_sent(MAVLINK_MSG_ID_COMMAND_ACK), "one COMMAND_ACK");
    TEST_ASSERT_EQUAL_UINT16(cmd, mavlink_msg_command_ack_get_command(&s_msg));
    TEST_ASSERT_EQUAL_UINT8(result, mavlink_msg_command_ack_get_result(&s_msg));
    TEST_ASSERT_EQUAL_INT32(reason, mavlink_msg_command_ack_get_result_param2(&s_msg));
    TEST_ASSERT_EQUAL_UINT8(HOST_SYS, mavlink_msg_command_ack_get_target_system(&s_msg));
}

static void test_link_command_with_nan_is_denied_not_finite(void)
{
    command(US, MAV_CMD_AGNAV_ESTOP, NAN, 0, 0);
    expect_ack(MAV_CMD_AGNAV_ESTOP, MAV_RESULT_DENIED, LINK_REFUSAL_NOT_FINITE);
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_link_command_with_infinity_is_denied_not_finite(void)
{
    command(US, MAV_CMD_AGNAV_SET_BEHAVIOURS, 1.0f, INFINITY, 0.0f);
    expect_ack(MAV_CMD_AGNAV_SET_BEHAVIOURS, MAV_RESULT_DENIED, LINK_REFUSAL_NOT_FINITE);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(LINK_ENABLE_AVOID, link_state()->behaviour_enable, "modes unchanged");
}

static void test_link_command_flag_other_than_0_or_1_is_denied_out_of_range(void)
{
    command(US, MAV_CMD_COMPONENT_ARM_DISARM, 0.7f, 0, 0);
    expect_ack(MAV_CMD_COMPONENT_ARM_DISARM, MAV_RESULT_DENIED, LINK_REFUSAL_OUT_OF_RANGE);
    TEST_ASSERT_FALSE(link_state()->arm_request);
}

static void test_link_unknown_command_is_unsupported_with_reason_and_counted(void)
{
    command(US, MAV_CMD_NAV_TAKEOFF, 0, 0, 0);
    expect_ack(MAV_CMD_NAV_TAKEOFF, MAV_RESULT_UNSUPPORTED, LINK_REFUSAL_UNSUPPORTED);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_link_broadcast_estop_is_accepted(void)
{
    command(0u, MAV_CMD_AGNAV_ESTOP, 1.0f, 0, 0);
    expect_ack(MAV_CMD_AGNAV_ESTOP, MAV_RESULT_ACCEPTED, 0);
    TEST_ASSERT_TRUE(link_state()->estop);
}

static void test_link_broadcast_arm_is_denied(void)
{
    command(0u, MAV_CMD_COMPONENT_ARM_DISARM, 1.0f, 0, 0);
    expect_ack(MAV_CMD_COMPONENT_ARM_DISARM, MAV_RESULT_DENIED, LINK_REFUSAL_BROADCAST);
    TEST_ASSERT_FALSE(link_state()->arm_request);
}

static void test_link_command_for_another_system_is_ignored_and_counted(void)
{
    command(7u, MAV_CMD_AGNAV_ESTOP, 1.0f, 0, 0);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(0u, robot_sent(MAVLINK_MSG_ID_COMMAND_ACK), "not ours: no answer");
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_other_target);
    TEST_ASSERT_EQUAL_UINT16(0u, link_state()->rx_refused);
}

/* Our system, a component it does not have: not acted on, not answered (nobody here speaks for that
 * component), but counted with the refusals, since it was sent to this robot. */
static void test_link_command_for_another_component_of_ours_is_refused_and_counted(void)
{
    mavlink_msg_command_long_pack(HOST_SYS, HOST_COMP, &s_msg, US, 42, MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT8(0u, robot_sent(MAVLINK_MSG_ID_COMMAND_ACK));
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
    TEST_ASSERT_EQUAL_UINT16(0u, link_state()->rx_other_target);
    mavlink_msg_param_request_list_pack(HOST_SYS, HOST_COMP, &s_msg, US, 42);
    send_to_robot(&s_msg);
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, US, 190, 0, 300, 0, 0, 0, 1);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    TEST_ASSERT_EQUAL_UINT16(3u, link_state()->rx_refused);
}

static void setpoint(uint8_t target, int16_t steer, int16_t speed, uint8_t mode, uint16_t spwm)
{
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, target, 1, steer, speed, 0, spwm, mode, 1);
    send_to_robot(&s_msg);
}

static void test_link_setpoint_out_of_range_is_refused_and_stops(void)
{
    setpoint(US, 100, 500, AGNAV_DRIVE_PHYSICAL, 0);
    TEST_ASSERT_TRUE(link_state()->setpoint.valid);
    setpoint(US, 100, 20000, AGNAV_DRIVE_PHYSICAL, 0);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->setpoint.valid, "a garbage setpoint drops the old one too");
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
    TEST_ASSERT_EQUAL_UINT8(1u, robot_sent(MAVLINK_MSG_ID_STATUSTEXT));
}

static void test_link_setpoint_steer_beyond_half_turn_is_refused(void)
{
    setpoint(US, -18001, 100, AGNAV_DRIVE_PHYSICAL, 0);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
}

/* The PWM fields are 0 in physical mode; beyond 3000 they are garbage in either mode. */
static void test_link_physical_setpoint_with_pwm_fields_beyond_3000_is_refused(void)
{
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 0, 100, 0, 3001, AGNAV_DRIVE_PHYSICAL, 1);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 0, 100, 65535, 0, AGNAV_DRIVE_PHYSICAL, 2);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    TEST_ASSERT_EQUAL_UINT16(2u, link_state()->rx_refused);
    setpoint(US, 0, 100, AGNAV_DRIVE_PHYSICAL, 0);
    TEST_ASSERT_TRUE(link_state()->setpoint.valid);
}

static void test_link_setpoint_unknown_mode_or_raw_pwm_range_is_refused(void)
{
    setpoint(US, 0, 100, 7u, 0);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    setpoint(US, 0, 100, AGNAV_DRIVE_RAW_PWM, 3001u);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    TEST_ASSERT_EQUAL_UINT16(2u, link_state()->rx_refused);
    setpoint(US, 0, 100, AGNAV_DRIVE_RAW_PWM, 200u);
    TEST_ASSERT_TRUE(link_state()->setpoint.valid);
}

static void test_link_broadcast_setpoint_is_refused(void)
{
    setpoint(0u, 0, 300, AGNAV_DRIVE_PHYSICAL, 0);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_link_refusal_texts_are_rate_limited_but_all_counted(void)
{
    for (uint8_t k = 0; k < 5u; k++) {
        setpoint(US, 0, 30000, AGNAV_DRIVE_PHYSICAL, 0);
    }
    TEST_ASSERT_EQUAL_UINT16(5u, link_state()->rx_refused);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(1u, robot_sent(MAVLINK_MSG_ID_STATUSTEXT), "one text per second");
}

static void test_link_truncated_setpoint_reads_as_broadcast_and_is_refused(void)
{
    /* A wrong (short) length: MAVLink 2 zero-fills the missing tail, so the target fields
     * at the end of the wire payload read 0 -> an unaddressed motion command. */
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 100, 400, 0, 0, 0, 1);
    mavlink_finalize_message(&s_msg, HOST_SYS, HOST_COMP, 1u, 4u, MAVLINK_MSG_ID_AGNAV_DRIVE_SETPOINT_CRC);
    TEST_ASSERT_EQUAL_UINT8(4u, s_msg.len);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_link_rc_pulse_outside_800_2200_is_refused(void)
{
    mavlink_msg_rc_channels_override_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 1600, 0, 2500, 0, 0, 0, 0, 0, 0, 0, 0,
                                          0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->manual.valid);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_link_rc_pulse_2100_is_clamped_to_full(void)
{
    mavlink_msg_rc_channels_override_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 1500, 0, 2100, 0, 0, 0, 0, 0, 0, 0, 0,
                                          0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    TEST_ASSERT_TRUE(link_state()->manual.valid);
    TEST_ASSERT_EQUAL_INT16(2000, link_state()->manual.speed_mm_s);
}

static void test_link_manual_control_axis_out_of_range_is_refused(void)
{
    mavlink_msg_manual_control_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1500, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                                    0);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->manual.valid);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

static void test_link_manual_control_broadcast_is_refused(void)
{
    mavlink_msg_manual_control_pack(HOST_SYS, HOST_COMP, &s_msg, 0u, 500, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                                    0);
    send_to_robot(&s_msg);
    TEST_ASSERT_FALSE(link_state()->manual.valid);
}

static void goal(uint8_t frame, uint16_t mask, float x, float y)
{
    mavlink_msg_set_position_target_local_ned_pack(HOST_SYS, HOST_COMP, &s_msg, 0, US, 1, frame, mask, x, y, 0, 0, 0,
                                                   0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
}

static void test_link_goal_nan_far_wrong_frame_or_ignored_xy_is_refused(void)
{
    goal(MAV_FRAME_LOCAL_NED, 0u, 2.0f, 1.0f);
    TEST_ASSERT_TRUE(link_state()->goal.active);
    goal(MAV_FRAME_LOCAL_NED, 0u, NAN, 1.0f);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->goal.active, "a refused goal drops the old one");
    goal(MAV_FRAME_LOCAL_NED, 0u, 2.0f, 20000.0f);
    goal(MAV_FRAME_BODY_NED, 0u, 2.0f, 1.0f);
    goal(MAV_FRAME_LOCAL_NED, 0x1u, 2.0f, 1.0f);
    TEST_ASSERT_FALSE(link_state()->goal.active);
    TEST_ASSERT_EQUAL_UINT16(4u, link_state()->rx_refused);
}

static void test_link_param_set_nan_or_huge_is_refused(void)
{
    mavlink_msg_param_set_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, "LINK_TIMEOUT_MS", NAN, MAV_PARAM_TYPE_INT32);
    send_to_robot(&s_msg);
    mavlink_msg_param_set_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, "LINK_TIMEOUT_MS", 3e9f, MAV_PARAM_TYPE_INT32);
    send_to_robot(&s_msg);
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_UINT16(2u, link_state()->rx_refused);
}

static void test_link_param_set_broadcast_is_refused(void)
{
    mavlink_msg_param_set_pack(HOST_SYS, HOST_COMP, &s_msg, 0u, 0u, "LINK_TIMEOUT_MS", 700.0f, MAV_PARAM_TYPE_INT32);
    send_to_robot(&s_msg);
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
}

/* PARAM_SET rounds half away from zero in float arithmetic, ties to even included (8388609.0f + 0.5f
 * is 8388610.0f): the firmware now works on the bits and must give the same integers. */
static void test_link_param_set_rounds_as_the_float_expression(void)
{
    static int32_t s_wide;
    static const PARAMS_ROM param_def_t WIDE[] = {{"WIDE", 0, PARAM_I32, &s_wide, -16777216, 16777216, 0}};
    static const PARAMS_ROM param_group_t WIDE_GROUP = PARAM_GROUP(WIDE);
    static const PARAMS_ROM param_group_ref_t WIDE_GROUPS[] = {&WIDE_GROUP};
    static const float V[] = {0.49999997f, 0.5f, 1.5f, 2.5f, -0.5f, -2.5f, 0.25f, 0.24999999f, 1e-30f, -0.0f,
                              1234.4999f, -1234.5f, 8388607.5f, 8388609.0f, 8388611.0f, -8388609.0f, 16777215.0f,
                              -16777215.0f, 4194304.5f, 0.75f};
    static const char ID[16] = "WIDE"; /* the pack copies all 16 bytes */
    params_init(WIDE_GROUPS, 1u);
    for (uint8_t i = 0; i < sizeof V / sizeof V[0]; i++) {
        volatile float f = V[i];
        int32_t want = (int32_t)(f >= 0.0f ? f + 0.5f : f - 0.5f);
        s_wide = 12345;
        mavlink_msg_param_set_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, ID, f, MAV_PARAM_TYPE_INT32);
        send_to_robot(&s_msg);
        TEST_ASSERT_EQUAL_INT32(want, s_wide);
    }
    TEST_ASSERT_EQUAL_UINT16(0u, link_state()->rx_refused);
}

/* Goal metres to millimetres as (int32_t)(x * 1000.0f) truncates a float product (also done on bits). */
static void test_link_goal_millimetres_are_the_truncated_float_product(void)
{
    static const float V[] = {0.0015f, -0.0015f, 0.001f, 0.003f, 2.0000002f, 9999.9995f, -10000.0f, 10000.0f,
                              1e-10f, 0.0f, -0.0f, 0.000999f, 123.4567f, -7.0625f, 1e-40f};
    for (uint8_t i = 0; i < sizeof V / sizeof V[0]; i++) {
        volatile float x = V[i], y = V[(i + 3u) % (sizeof V / sizeof V[0])];
        goal(MAV_FRAME_LOCAL_NED, 0u, x, y);
        TEST_ASSERT_TRUE(link_state()->goal.active);
        TEST_ASSERT_EQUAL_INT32((int32_t)(x * 1000.0f), link_state()->goal.x_mm);
        TEST_ASSERT_EQUAL_INT32((int32_t)(-y * 1000.0f), link_state()->goal.y_mm);
    }
    goal(MAV_FRAME_LOCAL_NED, 0u, 10000.001f, 0.0f);
    TEST_ASSERT_FALSE_MESSAGE(link_state()->goal.active, "just beyond 10 km");
}

/* Each command taken moves the count of its kind on (behaviour's failsafe hold reads a change as a
 * fresh command); a heartbeat, a parameter read and every refused command move none. */
static void test_link_only_taken_commands_count_as_new(void)
{
    const link_state_t *ls = link_state();
    mavlink_msg_heartbeat_pack(HOST_SYS, HOST_COMP, &s_msg, MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, 0);
    send_to_robot(&s_msg);
    mavlink_msg_param_request_read_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, "LINK_TIMEOUT_MS", -1);
    send_to_robot(&s_msg);
    setpoint(US, 0, 30000, AGNAV_DRIVE_PHYSICAL, 0);                    /* refused */
    goal(MAV_FRAME_LOCAL_NED, 0u, NAN, 1.0f);                            /* refused */
    command(US, MAV_CMD_AGNAV_SET_BEHAVIOURS, 2.0f, 0, 0);               /* refused */
    mavlink_msg_manual_control_pack(HOST_SYS, HOST_COMP, &s_msg, US, 2000, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);                                               /* refused */
    TEST_ASSERT_TRUE(ls->host_seen);
    TEST_ASSERT_EQUAL_UINT8(0u, ls->setpoint.gen);
    TEST_ASSERT_EQUAL_UINT8(0u, ls->goal.gen);
    TEST_ASSERT_EQUAL_UINT8(0u, ls->manual.gen);
    TEST_ASSERT_EQUAL_UINT8(0u, ls->behaviour_gen);

    setpoint(US, 0, 300, AGNAV_DRIVE_PHYSICAL, 0);
    setpoint(US, 0, 300, AGNAV_DRIVE_PHYSICAL, 0);
    goal(MAV_FRAME_LOCAL_NED, 0u, 2.0f, 1.0f);
    command(US, MAV_CMD_AGNAV_SET_BEHAVIOURS, 0.0f, 1.0f, 1.0f);
    mavlink_msg_manual_control_pack(HOST_SYS, HOST_COMP, &s_msg, US, 500, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    mavlink_msg_rc_channels_override_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 1500, 0, 1600, 0, 0, 0, 0, 0, 0, 0, 0,
                                          0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    TEST_ASSERT_EQUAL_UINT8(2u, ls->setpoint.gen);
    TEST_ASSERT_EQUAL_UINT8(1u, ls->goal.gen);
    TEST_ASSERT_EQUAL_UINT8(2u, ls->manual.gen);
    TEST_ASSERT_EQUAL_UINT8(1u, ls->behaviour_gen);
}

static uint8_t s_calib_calls;
static bool s_calib_refuses;

static bool calib_stub(const mavlink_message_t *msg)
{
    (void)msg;
    s_calib_calls++;
    return s_calib_refuses;
}

/* A calibration message is handed to main's handler only when addressed to the robot; a broadcast
 * is refused, one the handler refuses is counted. */
static void test_link_calibration_refusals_and_broadcasts_are_counted(void)
{
    link_cfg_t cfg = {US, 1u, 2460, 2000, calib_stub, 0u, 0};
    link_init(&cfg);
    s_calib_calls = 0u;
    s_calib_refuses = false;
    mavlink_msg_agnav_calib_request_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 1, AGNAV_CALIB_ACTION_READ);
    send_to_robot(&s_msg);
    TEST_ASSERT_EQUAL_UINT8(1u, s_calib_calls);
    TEST_ASSERT_EQUAL_UINT16(0u, link_state()->rx_refused);
    s_calib_refuses = true;
    mavlink_msg_agnav_calib_request_pack(HOST_SYS, HOST_COMP, &s_msg, US, 1, 1, 77u);
    send_to_robot(&s_msg);
    TEST_ASSERT_EQUAL_UINT8(2u, s_calib_calls);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_refused);
    mavlink_msg_agnav_calib_request_pack(HOST_SYS, HOST_COMP, &s_msg, 0u, 0u, 1, AGNAV_CALIB_ACTION_DEFAULTS);
    send_to_robot(&s_msg);
    static const uint16_t pwm[16] = {10, 255};
    static const int16_t val[16] = {20, 1000};
    mavlink_msg_agnav_calib_table_pack(HOST_SYS, HOST_COMP, &s_msg, 0u, 0u, 1, 2, pwm, val, 0, 0, 0);
    send_to_robot(&s_msg);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(2u, s_calib_calls, "a broadcast reached the calibration handler");
    TEST_ASSERT_EQUAL_UINT16(3u, link_state()->rx_refused);
    TEST_ASSERT_EQUAL_UINT8(1u, robot_sent(MAVLINK_MSG_ID_STATUSTEXT));
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_link_command_with_nan_is_denied_not_finite);
    RUN_TEST(test_link_command_with_infinity_is_denied_not_finite);
    RUN_TEST(test_link_command_flag_other_than_0_or_1_is_denied_out_of_range);
    RUN_TEST(test_link_unknown_command_is_unsupported_with_reason_and_counted);
    RUN_TEST(test_link_broadcast_estop_is_accepted);
    RUN_TEST(test_link_broadcast_arm_is_denied);
    RUN_TEST(test_link_command_for_another_system_is_ignored_and_counted);
    RUN_TEST(test_link_command_for_another_component_of_ours_is_refused_and_counted);
    RUN_TEST(test_link_setpoint_out_of_range_is_refused_and_stops);
    RUN_TEST(test_link_setpoint_steer_beyond_half_turn_is_refused);
    RUN_TEST(test_link_physical_setpoint_with_pwm_fields_beyond_3000_is_refused);
    RUN_TEST(test_link_setpoint_unknown_mode_or_raw_pwm_range_is_refused);
    RUN_TEST(test_link_broadcast_setpoint_is_refused);
    RUN_TEST(test_link_refusal_texts_are_rate_limited_but_all_counted);
    RUN_TEST(test_link_truncated_setpoint_reads_as_broadcast_and_is_refused);
    RUN_TEST(test_link_rc_pulse_outside_800_2200_is_refused);
    RUN_TEST(test_link_rc_pulse_2100_is_clamped_to_full);
    RUN_TEST(test_link_manual_control_axis_out_of_range_is_refused);
    RUN_TEST(test_link_manual_control_broadcast_is_refused);
    RUN_TEST(test_link_goal_nan_far_wrong_frame_or_ignored_xy_is_refused);
    RUN_TEST(test_link_param_set_nan_or_huge_is_refused);
    RUN_TEST(test_link_param_set_broadcast_is_refused);
    RUN_TEST(test_link_param_set_rounds_as_the_float_expression);
    RUN_TEST(test_link_goal_millimetres_are_the_truncated_float_product);
    RUN_TEST(test_link_only_taken_commands_count_as_new);
    RUN_TEST(test_link_calibration_refusals_and_broadcasts_are_counted);
    return UNITY_END();
}
