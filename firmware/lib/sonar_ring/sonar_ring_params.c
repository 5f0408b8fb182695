/* Sonar ring parameter (PARAM_* row 7): which preset ring is fitted, taken at boot. */
#include "params.h"
#include "sonar_ring.h"

uint8_t sonar_ring_param_count;

static const PARAMS_ROM param_def_t ROWS[] = {
    {"SONAR_COUNT", 7, PARAM_U8, &sonar_ring_param_count, 0, 12, 12}, /* 0 none, 1 SRF05, 6 HC-SR04, 12 ring */
};

const PARAMS_ROM param_group_t SONAR_RING_PARAM_GROUP = PARAM_GROUP(ROWS);

const sonar_ring_cfg_t *sonar_ring_for_count(uint8_t count)
{
    switch (count) {
    case 12u:
        return &SONAR_RING_12_SDLG;
    case 6u:
        return &SONAR_RING_6_HCSR04;
    case 1u:
        return &SONAR_RING_1_SRF05;
    default:
        return 0;
    }
}
