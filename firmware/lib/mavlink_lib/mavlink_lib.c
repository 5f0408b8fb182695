/* The one definition of MAVLink's helpers and of its channel status (sequence counters), see
 * mavlink_lib.h. protocol.h left MAVLINK_HELPER empty, so mavlink_helpers.h defines them extern here. */
#include "mavlink_lib.h"

/* Not the quaternion / DCM / Euler conversions: the firmware has no use for them (and they need libm). */
#define MAVLINK_NO_CONVERSION_HELPERS
#include <mavlink_helpers.h>
