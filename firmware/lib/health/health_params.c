/* Health monitor thresholds (PARAM_* rows 36..39); 0 switches a check off. PARAM_SET writes these
 * variables; main hands them to health_set_params() before the next control tick. */
#include "health.h"
#include "params.h"

health_params_t health_params;

static const PARAMS_ROM param_def_t ROWS[] = {
    /* the ref 003 car's slowest motion, 435 mm/s, gives a Hall pulse every 31 ms */
    {"HLTH_ENC_MS", 36, PARAM_U16, &health_params.enc_stuck_ms, 0, 10000, 500},
    {"HLTH_EDGE_MAX", 37, PARAM_U16, &health_params.enc_edges_max, 0, 60000, 2000},
    {"HLTH_SONAR_FR", 38, PARAM_U8, &health_params.sonar_fault_frames, 0, 50, 3},
    /* with the 3-sample median the fault latches ~0.5 s after it starts */
    {"HLTH_ZERO_FR", 39, PARAM_U8, &health_params.sonar_zero_frames, 0, 100, 4},
};

const PARAMS_ROM param_group_t HEALTH_PARAM_GROUP = PARAM_GROUP(ROWS);
