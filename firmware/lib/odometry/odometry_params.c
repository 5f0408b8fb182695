/* Odometry parameter (PARAM_* row 6): the Ackermann wheelbase, taken at boot. The track is the
 * drive's TRACK_MM. */
#include "odometry.h"
#include "params.h"

uint16_t odom_param_wheelbase_mm;

static const PARAMS_ROM param_def_t ROWS[] = {
    {"WHEELBASE_MM", 6, PARAM_U16, &odom_param_wheelbase_mm, 50, 2000, 174}, /* ref 003 car */
};

const PARAMS_ROM param_group_t ODOMETRY_PARAM_GROUP = PARAM_GROUP(ROWS);
