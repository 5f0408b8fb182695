/* Host link: frames in through the simulated UART, state and answers out. */
#include <string.h>
#include <unity.h>

#include "hal.h"
#include "link.h"
#include "link_wire.h"
#include "params.h"
#include "sim/hal_sim.h"

#define HOST_SYS 255u
#define HOST_COMP 190u

static uint16_t s_timeout_ms;
static const PARAMS_ROM param_def_t TABLE[] = {
    {"LINK_TIMEOUT_MS", 0, PARAM_U16, &s_timeout_ms, 100, 5000, 500},
};
static const PARAMS_ROM param_group_t GROUP = PARAM_GROUP(TABLE);
static const PARAMS_ROM param_group_ref_t GROUPS[] = {&GROUP};

static mavlink_message_t s_msg;

static void send_to_robot(const mavlink_message_t *msg) { wire_send(msg); }

/* Frames of msgid the robot sent (drained), the last one in s_msg. */
static uint8_t robot_sent(uint32_t msgid) { return wire_take(msgid, &s_msg); }

void setUp(void)
{
    sim_reset();
    params_init(GROUPS, 1u); /* LINK_TIMEOUT_MS 500 */
    link_cfg_t cfg = {1u, 1u, 2460, 2000, 0, 0u, 0};
    link_init(&cfg);
}

void tearDown(void) {}

static void test_link_drive_setpoint_is_decoded_and_counts_as_heartbeat(void)
{
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, -1250, 800, 0, 0,
                                          AGNAV_DRIVE_PHYSICAL, 9);
    send_to_robot(&s_msg);
    link_poll(1234u);
    const link_state_t *s = link_state();
    TEST_ASSERT_TRUE(s->setpoint.valid);
    TEST_ASSERT_EQUAL_INT16(-1250, s->setpoint.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(800, s->setpoint.speed_mm_s);
    TEST_ASSERT_EQUAL_UINT16(9u, s->setpoint.seq);
    TEST_ASSERT_EQUAL_UINT32(1234u, s->setpoint.rx_ms);
    TEST_ASSERT_EQUAL_UINT32(1234u, s->host_heartbeat_ms);
}

static void test_link_only_a_ground_stations_heartbeat_counts_as_the_host(void)
{
    /* another rover of the fleet, on the same radio net */
    mavlink_msg_heartbeat_pack(2, 1, &s_msg, MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(100u);
    TEST_ASSERT_FALSE(link_state()->host_seen);
    /* the host (a ground station) */
    mavlink_msg_heartbeat_pack(HOST_SYS, HOST_COMP, &s_msg, MAV_TYPE_GCS, MAV_AUTOPILOT_INVALID, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(200u);
    TEST_ASSERT_TRUE(link_state()->host_seen);
    TEST_ASSERT_EQUAL_UINT32(200u, link_state()->host_heartbeat_ms);
    /* later rover heartbeats leave the host's time alone */
    mavlink_msg_heartbeat_pack(2, 1, &s_msg, MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(900u);
    TEST_ASSERT_EQUAL_UINT32(200u, link_state()->host_heartbeat_ms);
}

static void test_link_setpoint_for_another_robot_is_ignored(void)
{
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, 7, 1, 100, 100, 0, 0, 0, 1);
    send_to_robot(&s_msg);
    link_poll(10u);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
}

static void test_link_bad_crc_is_counted_and_not_applied(void)
{
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    mavlink_msg_agnav_drive_setpoint_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, 100, 500, 0, 0, 0, 1);
    uint16_t len = mavlink_msg_to_send_buffer(buf, &s_msg);
    buf[12] ^= 0x10u; /* a payload bit flipped on the radio */
    wire_put(buf, len);
    link_poll(10u);
    TEST_ASSERT_FALSE(link_state()->setpoint.valid);
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->rx_errors);
}

static void test_link_estop_command_latches_and_is_acknowledged(void)
{
    mavlink_msg_command_long_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, MAV_CMD_AGNAV_ESTOP, 0, 1, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(10u);
    TEST_ASSERT_TRUE(link_state()->estop);
    TEST_ASSERT_EQUAL_UINT8(1u, robot_sent(MAVLINK_MSG_ID_COMMAND_ACK));
    TEST_ASSERT_EQUAL_UINT16(MAV_CMD_AGNAV_ESTOP, mavlink_msg_command_ack_get_command(&s_msg));
    TEST_ASSERT_EQUAL_UINT8(MAV_RESULT_ACCEPTED, mavlink_msg_command_ack_get_result(&s_msg));
}

static void test_link_unknown_command_is_answered_unsupported(void)
{
    mavlink_msg_command_long_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(10u);
    TEST_ASSERT_EQUAL_UINT8(1u, robot_sent(MAVLINK_MSG_ID_COMMAND_ACK));
    TEST_ASSERT_EQUAL_UINT8(MAV_RESULT_UNSUPPORTED, mavlink_msg_command_ack_get_result(&s_msg));
}

static void test_link_rc_override_right_stick_steers_right_negative(void)
{
    mavlink_msg_rc_channels_override_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, 2000, 0, 1750, 0, 0, 0, 0,
                                          0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(50u);
    const link_state_t *s = link_state();
    TEST_ASSERT_TRUE(s->manual.valid);
    TEST_ASSERT_EQUAL_INT16(-2460, s->manual.steer_cdeg);
    TEST_ASSERT_EQUAL_INT16(1000, s->manual.speed_mm_s);
}

static void test_link_rc_release_clears_manual(void)
{
    mavlink_msg_rc_channels_override_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0,
                                          0, 0, 0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(50u);
    TEST_ASSERT_FALSE(link_state()->manual.valid);
}

static void test_link_rc_to_range_dead_zone_and_saturation(void)
{
    TEST_ASSERT_EQUAL_INT16(0, link_rc_to_range(1510u, 1000));
    TEST_ASSERT_EQUAL_INT16(1000, link_rc_to_range(2100u, 1000));
    TEST_ASSERT_EQUAL_INT16(-500, link_rc_to_range(1250u, 1000));
    TEST_ASSERT_EQUAL_INT16(0, link_rc_to_range(UINT16_MAX, 1000));
}

static void test_link_ned_goal_is_converted_to_y_left(void)
{
    mavlink_msg_set_position_target_local_ned_pack(HOST_SYS, HOST_COMP, &s_msg, 0, 1, 1, MAV_FRAME_LOCAL_NED,
                                                   0, 3.0f, 2.0f, 0, 0, 0, 0, 0, 0, 0, 0, 0);
    send_to_robot(&s_msg);
    link_poll(50u);
    TEST_ASSERT_TRUE(link_state()->goal.active);
    TEST_ASSERT_EQUAL_INT32(3000, link_state()->goal.x_mm);
    TEST_ASSERT_EQUAL_INT32(-2000, link_state()->goal.y_mm);
}

static void test_link_param_set_out_of_range_is_refused(void)
{
    mavlink_msg_param_set_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, "LINK_TIMEOUT_MS", 99999.0f, MAV_PARAM_TYPE_INT32);
    send_to_robot(&s_msg);
    link_poll(50u);
    TEST_ASSERT_EQUAL_UINT16(500u, s_timeout_ms);
    TEST_ASSERT_EQUAL_UINT8(1u, robot_sent(MAVLINK_MSG_ID_PARAM_VALUE));
    TEST_ASSERT_EQUAL_FLOAT(500.0f, mavlink_msg_param_value_get_param_value(&s_msg));
}

static void test_link_param_set_in_range_is_applied_and_echoed(void)
{
    mavlink_msg_param_set_pack(HOST_SYS, HOST_COMP, &s_msg, 1, 1, "LINK_TIMEOUT_MS", 800.0f, MAV_PARAM_TYPE_INT32);
    send_to_robot(&s_msg);
    link_poll(50u);
    TEST_ASSERT_EQUAL_UINT16(800u, s_timeout_ms);
    TEST_ASSERT_EQUAL_UINT8(1u, robot_sent(MAVLINK_MSG_ID_PARAM_VALUE));
    TEST_ASSERT_EQUAL_FLOAT(800.0f, mavlink_msg_param_value_get_param_value(&s_msg));
}

static void test_link_send_drops_and_counts_when_uart_full(void)
{
    uint8_t filler[64];
    memset(filler, 0x55, sizeof filler);
    while (hal_uart_write(HAL_UART_LINK, filler, sizeof filler) == sizeof filler) {
    }
    mavlink_msg_heartbeat_pack(1, 1, &s_msg, MAV_TYPE_GROUND_ROVER, MAV_AUTOPILOT_GENERIC, 0, 0, 0);
    TEST_ASSERT_FALSE(link_send(&s_msg));
    TEST_ASSERT_EQUAL_UINT16(1u, link_state()->tx_drops);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_link_drive_setpoint_is_decoded_and_counts_as_heartbeat);
    RUN_TEST(test_link_only_a_ground_stations_heartbeat_counts_as_the_host);
    RUN_TEST(test_link_setpoint_for_another_robot_is_ignored);
    RUN_TEST(test_link_bad_crc_is_counted_and_not_applied);
    RUN_TEST(test_link_estop_command_latches_and_is_acknowledged);
    RUN_TEST(test_link_unknown_command_is_answered_unsupported);
    RUN_TEST(test_link_rc_override_right_stick_steers_right_negative);
    RUN_TEST(test_link_rc_release_clears_manual);
    RUN_TEST(test_link_rc_to_range_dead_zone_and_saturation);
    RUN_TEST(test_link_ned_goal_is_converted_to_y_left);
    RUN_TEST(test_link_param_set_out_of_range_is_refused);
    RUN_TEST(test_link_param_set_in_range_is_applied_and_echoed);
    RUN_TEST(test_link_send_drops_and_counts_when_uart_full);
    return UNITY_END();
}
