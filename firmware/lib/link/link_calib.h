/*
 * AGNAV_CALIB_TABLE <-> calib_table_t.
 *
 * On the wire a table is one list of (pwm, value) points sorted by pwm plus
 * the neutral pwm. Points with value > 0 form the positive side (left turn /
 * forward), value < 0 the negative side; a point with value 0 belongs to the
 * side lying on the same side of neutral as that side's other points. Each
 * side is ordered outward from neutral for calib_validate(). The dead-band
 * fields are informative when the robot sends a table (the innermost pwm of
 * each side) and ignored when the host writes one: the gap between the
 * innermost points is the dead band.
 */
#ifndef AGNAV_LINK_CALIB_H
#define AGNAV_LINK_CALIB_H

#include "calib.h"
#include "mavlink_lib.h"

/* Returns 0 on success, AGNAV_CALIB_BAD_TABLE when the points cannot form two sides
 * (too many points on a side, or a zero point that fits neither side). */
uint8_t link_calib_from_msg(const mavlink_agnav_calib_table_t *msg, calib_table_t *out);
void link_calib_to_msg(uint8_t table_id, const calib_table_t *t, mavlink_agnav_calib_table_t *out);
/* calib_status_t -> AGNAV_CALIB_RESULT. */
uint8_t link_calib_result(calib_status_t status);

#endif
