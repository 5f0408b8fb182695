/* The host's side of the link UART for the link test programs (test_link, test_link_safety,
 * test_signing): put a whole frame in the robot's receive queue, and decode what the robot sent.
 * Header-only (static inline): each test program is its own executable. */
#ifndef AGNAV_TEST_LINK_WIRE_H
#define AGNAV_TEST_LINK_WIRE_H

#include <string.h>
#include <unity.h>

#include "hal.h"
#include "link.h"
#include "sim/hal_sim.h"

/* Queue len bytes for the robot's link UART; the whole frame must fit. */
static inline void wire_put(const uint8_t *buf, uint16_t len)
{
    TEST_ASSERT_EQUAL_UINT16(len, sim_uart_put_rx(HAL_UART_LINK, buf, len));
}

/* Queue msg as the wire bytes a host would send. */
static inline void wire_send(const mavlink_message_t *msg)
{
    uint8_t buf[MAVLINK_MAX_PACKET_LEN];
    wire_put(buf, mavlink_msg_to_send_buffer(buf, msg));
}

#define WIRE_ANY_MSG UINT32_MAX

/* Drain everything the robot sent; returns how many frames of msgid (WIRE_ANY_MSG: of any id) were
 * in it, the last one in *last. Frames of other ids are dropped with the rest of the drained bytes. */
static inline uint8_t wire_take(uint32_t msgid, mavlink_message_t *last)
{
    static mavlink_message_t rx;
    static mavlink_status_t st;
    uint8_t b;
    uint8_t n = 0;
    memset(&st, 0, sizeof st);
    while (sim_uart_take_tx(HAL_UART_LINK, &b, 1u) == 1u) {
        if (mavlink_frame_char_buffer(&rx, &st, b, NULL, NULL) == MAVLINK_FRAMING_OK &&
            (msgid == WIRE_ANY_MSG || rx.msgid == msgid)) {
            *last = rx;
            n++;
        }
    }
    return n;
}

#endif
