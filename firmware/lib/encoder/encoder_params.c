/* Wheel encoder parameters (PARAM_* rows 2, 3, 4 and 41): the robot's build, taken at boot by
 * encoder_init_params(). Units are in the names. */
#include <string.h>

#include "encoder.h"
#include "params.h"

/* Build-time overrides of the robot profile (benchmark and board variants). */
#ifndef AGNAV_DEFAULT_ENC_COUNT
#define AGNAV_DEFAULT_ENC_COUNT 1
#endif
#ifndef AGNAV_DEFAULT_ENC_MODE
#define AGNAV_DEFAULT_ENC_MODE ENCODER_MODE_HALL
#endif
#ifndef AGNAV_DEFAULT_ENC_NM_PER_CNT
#define AGNAV_DEFAULT_ENC_NM_PER_CNT 13550000L /* ref 003 car: 16 magnets, 13.55 mm per pulse */
#endif

encoder_params_t encoder_params;

static const PARAMS_ROM param_def_t ROWS[] = {
    {"ENC_COUNT", 2, PARAM_U8, &encoder_params.count, 1, 4, AGNAV_DEFAULT_ENC_COUNT},
    {"ENC_MODE", 3, PARAM_U8, &encoder_params.mode, 0, 1, AGNAV_DEFAULT_ENC_MODE},
    {"ENC_NM_PER_CNT", 4, PARAM_I32, &encoder_params.nm_per_count, 1000, 16000000, AGNAV_DEFAULT_ENC_NM_PER_CNT},
    {"ENC_INVERT", 41, PARAM_U8, &encoder_params.invert, 0, 15, 0},
};

const PARAMS_ROM param_group_t ENCODER_PARAM_GROUP = PARAM_GROUP(ROWS);

bool encoder_init_params(const encoder_params_t *p)
{
    encoder_cfg_t cfg[ENCODER_MAX];
    memset(cfg, 0, sizeof cfg);
    for (uint8_t i = 0; i < p->count && i < ENCODER_MAX; i++) {
        cfg[i].mode = p->mode;
        cfg[i].invert = (uint8_t)((p->invert >> i) & 1u);
        cfg[i].travel_per_count_nm = (uint32_t)p->nm_per_count;
    }
    return encoder_init(p->count, cfg);
}
