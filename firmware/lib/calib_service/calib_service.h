/*
 * The calibration tables over the link: AGNAV_CALIB_TABLE writes a table this output stage can drive,
 * AGNAV_CALIB_REQUEST reads one (the table is the answer), saves them all (lib/storage writes them in
 * the background; answered IN_PROGRESS now and ACCEPTED or STORAGE_ERROR when written) or restores a
 * table's default; any other action is refused OUT_OF_RANGE. Every message gets an AGNAV_CALIB_ACK
 * (or the table). lib/link/link_calib.c converts between the message and calib_table_t, lib/calib
 * keeps the tables, lib/drive says which tables its outputs can drive.
 */
#ifndef AGNAV_CALIB_SERVICE_H
#define AGNAV_CALIB_SERVICE_H

#include <stdbool.h>
#include <stdint.h>

#include "mavlink_lib.h"

#ifdef __cplusplus
extern "C" {
#endif

/* After calib_load(): a stored table this output stage cannot drive (written by an older firmware,
 * e.g. in servo microseconds: full throttle here) is replaced by its default, as
 * calib_service_on_msg() refuses such writes. */
void calib_service_drop_unfit(void);

/* AGNAV_CALIB_TABLE or AGNAV_CALIB_REQUEST from link_poll() (link_cfg_t's calibration handler):
 * answered here; true when it was refused (the link counts it). */
bool calib_service_on_msg(const mavlink_message_t *in);

/* storage_take_done()'s records (STORAGE_BIT mask) and those that failed: the final answer to a
 * save request once the tables are written. */
void calib_service_storage_done(uint8_t done, uint8_t failed);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_CALIB_SERVICE_H */
