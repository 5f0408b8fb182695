/* Drive parameters (PARAM_* rows 1 and 5): the robot's build, taken at boot (drive_init(&drive_params),
 * and odometry's track). Units are in the names. */
#include "drive.h"
#include "params.h"

/* Build-time override of the robot profile (benchmark and board variants). */
#ifndef AGNAV_DEFAULT_DRIVE_KIND
#define AGNAV_DEFAULT_DRIVE_KIND DRIVE_ACKERMANN
#endif

drive_cfg_t drive_params; /* spin_mm_s, spin_below_mm_s: 0, drive.c's defaults */

static const PARAMS_ROM param_def_t ROWS[] = {
    {"DRIVE_KIND", 1, PARAM_U8, &drive_params.kind, 0, 1, AGNAV_DEFAULT_DRIVE_KIND},
    {"TRACK_MM", 5, PARAM_U16, &drive_params.track_mm, 50, 2000, 191},
};

const PARAMS_ROM param_group_t DRIVE_PARAM_GROUP = PARAM_GROUP(ROWS);
