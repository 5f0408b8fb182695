/* Signing parameter (PARAM_* row 40): sign sent frames while a key is set (received ones are always
 * checked). main applies it every link task (signing_set_sign_telemetry). */
#include "params.h"
#include "signing.h"

uint8_t signing_param_sign_telem;

static const PARAMS_ROM param_def_t ROWS[] = {
    {"SIGN_TELEM", 40, PARAM_U8, &signing_param_sign_telem, 0, 1, 1},
};

const PARAMS_ROM param_group_t SIGNING_PARAM_GROUP = PARAM_GROUP(ROWS);
