/*
 * Sensor health monitor: turns what the encoder and sonar front ends report into
 * latched fault bits, which lib/control feeds to the behaviour failsafe (controlled stop) and
 * lib/telemetry reports (STATUSTEXT once per new fault, NAMED_VALUE_INT "HEALTH" and SYS_STATUS health
 * bits). Pure logic: no HAL calls, time comes from the caller. docs/safety.md gives the
 * reasoning and the tests for each check.
 *
 * Encoders (health_encoders(), every control tick):
 *   stuck    the drive is driving (output not neutral) and wheel i has not counted for
 *            enc_stuck_ms: a broken magnet or sensor, an unplugged connector (lines float
 *            to a constant level), a slipping coupling, or the robot is blocked. Each
 *            of these calls for a stop.
 *   errors   the front end's error ratio (> 1/8 illegal transitions over 64 edges:
 *            ENCODER_F_ERROR_RATIO), or more than enc_edges_max edges in one tick (faster
 *            than any wheel turns: noise or a shorted line ringing). Either means the
 *            counts cannot be trusted.
 * Sonars (health_sonar(), every new ring frame):
 *   timeout  sensor i was SONAR_FAULT (echo never rose within 4 ms of the trigger, or the
 *            line was stuck high) in sonar_fault_frames frames in a row. Free space is
 *            different: the echo does rise and runs to max range (SONAR_NO_ECHO).
 *   zero     sensor i read VALID but closer than HEALTH_SONAR_ZERO_MM (below any HC-SR04 /
 *            SRF05 minimum range) in sonar_zero_frames frames in a row: a shorted or ringing
 *            transducer that would hide every real obstacle behind a fake one.
 * Bits latch until health_clear() (main calls it when the host arms) and are set again if
 * the condition persists. A parameter of 0 switches its check off.
 */
#ifndef AGNAV_HEALTH_H
#define AGNAV_HEALTH_H

#include <stdbool.h>
#include <stdint.h>

#include "params.h"
#include "sonar_ring.h"

#ifdef __cplusplus
extern "C" {
#endif

#define HEALTH_ENC_MAX 4u
#define HEALTH_SONAR_ZERO_MM 20u

/* health_bits() layout (also the NAMED_VALUE_INT "HEALTH" value). */
#define HEALTH_ENC_STUCK_SHIFT 0u   /* bits 0..3: wheel i stuck */
#define HEALTH_ENC_ERROR_SHIFT 4u   /* bits 4..7: wheel i illegal transitions / edge storm */
#define HEALTH_SONAR_TIMEOUT_SHIFT 8u  /* bits 8..19: sonar i never echoes */
#define HEALTH_SONAR_ZERO_SHIFT 20u    /* bits 20..31: sonar i reads zero */
#define HEALTH_ENC_MASK 0x000000FFUL
#define HEALTH_SONAR_MASK 0xFFFFFF00UL

/* Thresholds: the PARAM_* rows, ranges and defaults in health_params.c. */
typedef struct {
    uint16_t enc_stuck_ms;      /* driving without counts this long -> stuck; 0 off */
    uint16_t enc_edges_max;     /* edges of one wheel in one control tick above this -> error; 0 off */
    uint8_t sonar_fault_frames; /* consecutive FAULT frames of one sensor -> timeout; 0 off */
    uint8_t sonar_zero_frames;  /* consecutive frames closer than 20 mm -> zero; 0 off */
} health_params_t;

/* The parameter variables (health_params.c): PARAM_SET changes them, the monitor takes them with
 * health_set_params(). */
extern health_params_t health_params;
extern const PARAMS_ROM param_group_t HEALTH_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */

/* Reset all state; params are copied (main: &health_params). */
void health_init(const health_params_t *params, uint8_t enc_count);

/* New thresholds (PARAM_SET at run time), used from the next check; the counters are kept. */
void health_set_params(const health_params_t *params);

/* One control tick. driving: the drive output is not neutral. count_lo / edges_lo: the low
 * 16 bits of each wheel's count and edge total (encoder_snapshot_t); ratio_faults: bit i =
 * wheel i has ENCODER_F_ERROR_RATIO (encoder_faults()). */
void health_encoders(uint32_t now_ms, bool driving, const uint16_t *count_lo, const uint16_t *edges_lo,
                     uint8_t ratio_faults);

/* One new, complete sonar ring frame. */
void health_sonar(const sonar_frame_t *frame);

uint32_t health_bits(void);
bool health_encoder_fault(void);
bool health_sonar_fault(void);
/* The lowest bit latched and not yet taken (0 if none): each fault is reported once, one
 * per call. */
uint32_t health_take_new(void);
/* Drop the latches (host armed again); a persisting fault latches again. */
void health_clear(void);

#ifdef __cplusplus
}
#endif

#endif
