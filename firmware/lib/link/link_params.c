/* Link parameter (PARAM_* row 0): this robot's MAVLink system id, taken at boot. */
#include "link.h"
#include "params.h"

uint8_t link_param_sysid;

static const PARAMS_ROM param_def_t ROWS[] = {
    {"SYSID_THISMAV", 0, PARAM_U8, &link_param_sysid, 1, 250, 1},
};

const PARAMS_ROM param_group_t LINK_PARAM_GROUP = PARAM_GROUP(ROWS);
