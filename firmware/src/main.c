/* AgNav robot controller: wiring and the scheduler table only. */
#include "hal.h"

#include <agnav_mavlink.h>

static mavlink_system_t s_system = {1, MAV_COMP_ID_AUTOPILOT1};

static void send_heartbeat(void)
{
    mavlink_message_t msg;
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    mavlink_msg_heartbeat_pack(s_system.sysid, s_system.compid, &msg, MAV_TYPE_GROUND_ROVER,
                               MAV_AUTOPILOT_GENERIC, 0, 0, MAV_STATE_ACTIVE);
    uint16_t len = mavlink_msg_to_send_buffer(buf, &msg);
    hal_uart_write(HAL_UART_LINK, buf, len);
}

int main(void)
{
    hal_init();
    hal_uart_init(HAL_UART_LINK, 57600u);
    uint32_t next_ms = 0;
    for (;;) {
        uint32_t now = hal_time_ms();
        if ((int32_t)(now - next_ms) >= 0) {
            next_ms += 1000u;
            send_heartbeat();
        }
    }
}
