/* Behaviour parameters (PARAM_* rows 8..35): the layers' tunables and the layers enabled at boot.
 * PARAM_SET writes these variables; main hands them to behaviour_set_params() before the next
 * control tick. Units are in the names. */
#include "behaviour.h"
#include "params.h"

/* Build-time override of the layers enabled at boot (benchmark and board variants). */
#ifndef AGNAV_DEFAULT_MODES
#define AGNAV_DEFAULT_MODES BHV_MODE_AVOID
#endif

behaviour_params_t behaviour_params;
uint8_t behaviour_boot_modes;

static const PARAMS_ROM param_def_t ROWS[] = {
    {"BHV_MODES", 8, PARAM_U8, &behaviour_boot_modes, 0, 7, AGNAV_DEFAULT_MODES},
    {"LINK_TIMEOUT_MS", 9, PARAM_U16, &behaviour_params.link_timeout_ms, 100, 5000, 500},
    {"MAX_SPEED_MM_S", 10, PARAM_I16, &behaviour_params.max_speed_mm_s, 0, 3000, 1000},
    {"MAX_STEER_CDEG", 11, PARAM_I16, &behaviour_params.max_steer_cdeg, 0, 4500, 3000},
    {"AVOID_STOP_MM", 12, PARAM_U16, &behaviour_params.avoid_stop_mm, 50, 3000, 300},
    {"AVOID_BACKOFF_MM", 13, PARAM_U16, &behaviour_params.avoid_backoff_mm, 0, 500, 50},
    {"AVOID_WAIT_MS", 14, PARAM_U16, &behaviour_params.avoid_wait_ms, 0, 10000, 1000},
    {"WALL_R0_MM", 15, PARAM_U16, &behaviour_params.wall_r0_mm, 0, 1000, 100},
    {"WALL_SPEED_MM_S", 16, PARAM_I16, &behaviour_params.wall_speed_mm_s, 0, 2000, 300},
    {"WALL_CANYON_MS", 17, PARAM_U16, &behaviour_params.wall_canyon_ms, 0, 10000, 1500},
    {"GOAL_SPEED_MM_S", 18, PARAM_I16, &behaviour_params.goal_speed_mm_s, 0, 2000, 400},
    {"GOAL_TOL_MM", 19, PARAM_U16, &behaviour_params.goal_tol_mm, 10, 2000, 100},
    {"HOST_TIMEOUT_MS", 20, PARAM_U16, &behaviour_params.host_timeout_ms, 100, 5000, 500},
    {"MAN_TIMEOUT_MS", 21, PARAM_U16, &behaviour_params.manual_timeout_ms, 100, 5000, 300},
    {"AVOID_CONE_CDEG", 22, PARAM_I16, &behaviour_params.avoid_cone_cdeg, 500, 9000, 3000},
    {"AVOID_MOVE_MM_S", 23, PARAM_I16, &behaviour_params.avoid_moving_mm_s, 0, 500, 20},
    {"AVOID_STOP_MS", 24, PARAM_U16, &behaviour_params.avoid_stop_ms, 0, 5000, 200},
    {"AVOID_BACK_MM_S", 25, PARAM_I16, &behaviour_params.avoid_backoff_speed_mm_s, 20, 1000, 100},
    {"AVOID_REAR_MM", 26, PARAM_U16, &behaviour_params.avoid_rear_clear_mm, 0, 2000, 150},
    {"WALL_DT_MS", 27, PARAM_U16, &behaviour_params.wall_dt_ms, 20, 1000, 100},
    {"WALL_IMAX_STEPS", 28, PARAM_U8, &behaviour_params.wall_imax_steps, 1, 100, 10},
    {"WALL_IMIN_STEPS", 29, PARAM_U8, &behaviour_params.wall_imin_steps, 1, 200, 50},
    {"WALL_DEADBAND", 30, PARAM_U16, &behaviour_params.wall_deadband, 0, 10000, 100},
    {"WALL_GAIN_Q4", 31, PARAM_U8, &behaviour_params.wall_gain_q4, 0, 255, 32},
    {"WALL_TURN_CDEG", 32, PARAM_I16, &behaviour_params.wall_turn_steer_cdeg, 0, 4500, 2000},
    {"WALL_TIE_DIR", 33, PARAM_I8, &behaviour_params.wall_tie_dir, -1, 1, -1},
    {"GOAL_MIN_MM_S", 34, PARAM_I16, &behaviour_params.goal_min_speed_mm_s, 0, 2000, 80},
    {"GOAL_SLOW_MM", 35, PARAM_U16, &behaviour_params.goal_slow_mm, 0, 10000, 1000},
};

const PARAMS_ROM param_group_t BEHAVIOUR_PARAM_GROUP = PARAM_GROUP(ROWS);
