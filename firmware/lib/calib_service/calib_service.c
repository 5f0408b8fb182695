/* The calibration messages' handler, see calib_service.h. */
#include "calib_service.h"

#include "calib.h"
#include "control.h"
#include "drive.h"
#include "link.h"
#include "link_calib.h"
#include "storage.h"

static uint8_t s_save_id; /* table id of the save request in progress (echoed in its final ack) */

static void send_ack(uint8_t id, uint8_t result)
{
    mavlink_message_t msg;
    mavlink_msg_agnav_calib_ack_pack(link_sysid(), link_compid(), &msg, id, result, 255u,
                                     control_out()->failsafe_flags);
    (void)link_send(&msg);
}

void calib_service_drop_unfit(void)
{
    for (uint8_t id = 0; id < (uint8_t)CALIB_TABLE_COUNT; id++) {
        calib_table_t t;
        if (calib_get_table(id, &t) && !drive_table_fits(id, &t)) {
            calib_use_default(id);
        }
    }
}

bool calib_service_on_msg(const mavlink_message_t *in)
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
            storage_request(STORAGE_CALIB); /* the final answer: calib_service_storage_done() */
            s_save_id = id;
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
            (void)link_send(&msg);
            return false;
        } else {
            result = AGNAV_CALIB_BAD_TABLE;
        }
    }
    send_ack(id, result);
    return result != AGNAV_CALIB_ACCEPTED && result != AGNAV_CALIB_IN_PROGRESS;
}

void calib_service_storage_done(uint8_t done, uint8_t failed)
{
    if ((done & STORAGE_BIT(STORAGE_CALIB)) != 0u) {
        bool ok = (failed & STORAGE_BIT(STORAGE_CALIB)) == 0u;
        calib_saved(ok);
        send_ack(s_save_id, ok ? AGNAV_CALIB_ACCEPTED : AGNAV_CALIB_STORAGE_ERROR);
    }
}
