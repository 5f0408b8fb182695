/*
 * Sonar ring front end: up to 12 trigger/echo rangers (HC-SR04, SRF05 class).
 *
 * Split in the usual AgNav way:
 *   - sonar_ring_isr_echo() is the HAL echo-edge hook (interrupt context, or
 *     loop context from hal_sonar_poll() on the AVR, whose echo vectors only
 *     queue records). It only keeps the time of the first rising and the first
 *     falling edge after each trigger, and the line level.
 *   - sonar_ring_step() runs from the main loop as often as possible (every
 *     loop pass, >= 1 kHz is ideal): it fires the sensor groups on schedule,
 *     classifies finished echoes, converts them to millimetres, filters them
 *     and publishes a complete ring.
 *   - sonar_ring_snapshot() hands one consistent frame (all sensors of the
 *     same ring pass) to the behaviour layers.
 *
 * Firing schedule (cross-talk rule: a sensor never fires within
 * SONAR_NEIGHBOUR_GAP_US of a neighbour, neighbour = adjacent index in the
 * ring, wrapping 11 <-> 0):
 *   sensor i belongs to group i % 3, so a 12-ring fires {0,3,6,9}, then
 *   {1,4,7,10}, then {2,5,8,11}: members of a group sit 90 deg apart and two
 *   neighbours are never in the same group. Each group firing starts at least
 *   SONAR_SLOT_US after the previous group firing (it is scheduled relative to
 *   the real previous firing, so a late loop pass only ever widens the gap).
 *   Hence any two neighbour triggers are >= SONAR_SLOT_US >= 30 ms apart, and
 *   the whole ring repeats every 3 * 32 ms = 96 ms (10.4 Hz) instead of the
 *   12 * ~33 ms = 400 ms (2.5 Hz) of firing one sensor at a time.
 *   An echo still high at its max-range timeout is decided when it falls (free
 *   space) or at SONAR_FALL_TIMEOUT_US (stuck line). The pass's frame waits for
 *   those verdicts (an HC-SR04 in free space in the last group: ~6.5 ms); the
 *   next group fires on time and is classified after the frame is out. A ring of
 *   one group (1 sensor) fires a sensor again only after its echo ended.
 *   Rings whose size leaves sensor n-1 and sensor 0 in the same group (n = 4,
 *   7, 10) move sensor n-1 to group 1; rings of 1 or 2 sensors use 1 or 2 groups.
 *
 * Echo width to range: sound travels ~343 m/s (dry air, 20 degC) =
 * 0.343 mm/us, and the echo pulse covers the round trip, so
 *   range_mm = echo_us * 0.343 / 2 = echo_us * 343 / 2000   (rounded).
 * At 0 degC (331 m/s) the error is -3.5 %, at 35 degC (352 m/s) +2.6 %.
 *
 * Units: _mm millimetres, _us microseconds, _cdeg hundredths of a degree.
 * Frame: REP-103, x forward, y left, bearings counter-clockwise positive
 * (0 = straight ahead, 9000 = left, -9000 = right, 18000 = back).
 */
#ifndef AGNAV_SONAR_RING_H
#define AGNAV_SONAR_RING_H

#include <stdbool.h>
#include <stdint.h>
#include "params.h"
#include "units.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SONAR_RING_MAX 12u
#define SONAR_GROUPS 3u                 /* group = index % SONAR_GROUPS */
#define SONAR_SLOT_US 32000UL           /* minimum time between two group firings */
#define SONAR_NEIGHBOUR_GAP_US 30000UL  /* cross-talk rule for adjacent sensors */
#define SONAR_RISE_TIMEOUT_US 4000UL    /* trigger -> echo rising edge; later = FAULT */
/* Trigger -> echo falling edge; a line still high later is stuck = FAULT. A working sensor ends
 * every pulse well before: an HC-SR04 holds the echo 38 ms when nothing is in range, an SRF05
 * (Devantech technical specification) about 30 ms. */
#define SONAR_FALL_TIMEOUT_US 50000UL
#define SONAR_RING_PERIOD_US (SONAR_GROUPS * SONAR_SLOT_US)

/* Reading status; numeric values are part of the telemetry protocol. */
typedef enum {
    SONAR_VALID = 0,   /* echo received: range_mm is the median-filtered distance */
    SONAR_NO_ECHO = 1, /* echo pulse ran past the max-range timeout and then ended (within
                          SONAR_FALL_TIMEOUT_US of the trigger): free space, range_mm = max_range_mm */
    SONAR_FAULT = 2,   /* no rising edge within SONAR_RISE_TIMEOUT_US after the trigger, the echo
                          line was still high when triggered, or the echo did not fall within
                          SONAR_FALL_TIMEOUT_US (line stuck high: e.g. an unplugged sensor on a
                          pulled-up pin, board.h): range_mm = 0 */
    SONAR_STALE = 3    /* not measured in this ring pass (not yet measured since init, or
                          skipped by the cross-talk guard): range_mm = 0 */
} sonar_status_t;

/* Const per-sensor mounting description (lives in flash). */
typedef struct {
    int16_t bearing_cdeg;  /* mounting direction, 0 = forward, CCW positive, -18000..18000 */
    int16_t x_mm;          /* sensor position in the body frame, x forward */
    int16_t y_mm;          /* y left */
    uint16_t max_range_mm; /* echo longer than this counts as NO_ECHO (max ~4800 mm, see init) */
} sonar_cfg_t;

typedef struct {
    const UNITS_ROM sonar_cfg_t *sensor; /* in flash on the AVR; count entries, ordered around the ring (index = HAL sonar idx) */
    uint8_t count;             /* 1..SONAR_RING_MAX */
} sonar_ring_cfg_t;

/* Presets.
 * SONAR_RING_12_SDLG: ref 002's ring, S0 front, S3 left, S6 back, S9 right,
 *   30 deg apart, on a 225 mm radius (450 mm robot), 4 m range.
 * SONAR_RING_6_HCSR04: ref 001's layout, idx 0 front, 1/2 left (front/rear),
 *   3 back, 4/5 right (rear/front), HC-SR04, 4 m.
 * SONAR_RING_1_SRF05: a single forward SRF05, 4 m. */
extern const sonar_ring_cfg_t SONAR_RING_12_SDLG;
extern const sonar_ring_cfg_t SONAR_RING_6_HCSR04;
extern const sonar_ring_cfg_t SONAR_RING_1_SRF05;

/* The parameter (sonar_ring_params.c: SONAR_COUNT, taken at boot) and its preset:
 * 12, 6, 1 -> the ring above, anything else -> NULL (no sonar). */
extern uint8_t sonar_ring_param_count;
extern const PARAMS_ROM param_group_t SONAR_RING_PARAM_GROUP; /* the rows, for main's PARAM_GROUPS */
const sonar_ring_cfg_t *sonar_ring_for_count(uint8_t count);

/* One complete ring pass, as handed to the behaviour layers. */
typedef struct {
    uint16_t ranges_mm[SONAR_RING_MAX]; /* see sonar_status_t for the meaning per status */
    uint8_t status[SONAR_RING_MAX];     /* sonar_status_t values */
    uint32_t stamp_us;                  /* hal time when the ring pass completed */
    uint32_t seq;                       /* ring passes completed since init (0 = none yet) */
    uint8_t count;                      /* sensors in the ring */
} sonar_frame_t;

/* Reset all state, take cfg (kept by pointer, must stay valid) and attach
 * the echo hook with hal_sonar_attach(). Max ranges longer than the slot
 * allows (SONAR_SLOT_US - SONAR_RISE_TIMEOUT_US of echo, ~4.8 m) are clamped.
 * Returns false (ring disabled) if cfg is NULL or count is 0 or > 12. */
bool sonar_ring_init(const sonar_ring_cfg_t *cfg);

/* HAL echo-edge hook (hal_echo_edge_fn). Interrupt context: records the time
 * of the first rising edge and of the first falling edge after a trigger,
 * and the current line level. level: 1 rising, 0 falling; t_us: hal time. */
void sonar_ring_isr_echo(uint8_t idx, uint8_t level, uint32_t t_us);

/* Loop-side work; call often with now_us = hal_time_us(). Fires the next
 * group when due (hal_sonar_trigger), classifies finished echoes and
 * publishes a frame when the last group of a pass is done. */
void sonar_ring_step(uint32_t now_us);

/* Copy the latest complete frame into *out. Returns true if a ring pass
 * completed since the previous call (i.e. the frame is new). */
bool sonar_ring_snapshot(sonar_frame_t *out);

/* Ring passes completed since init (same as the latest frame's seq). */
uint32_t sonar_ring_frames_completed(void);

/* FAULT classifications of sensor idx since init (saturates at 65535). */
uint16_t sonar_ring_fault_count(uint8_t idx);

/* Firings skipped by the cross-talk guard since init (0 unless the schedule
 * were wrong: the guard is a second line of defence). */
uint16_t sonar_ring_guard_skips(void);

/* Group (firing slot) of sensor idx for the current configuration. */
uint8_t sonar_ring_group_of(uint8_t idx);

/* True if no two ring neighbours share a group (the static half of the
 * cross-talk proof; the timing half is SONAR_SLOT_US >= the gap). */
bool sonar_ring_schedule_ok(void);

/* Echo pulse width (us) to one-way range (mm), rounded, saturating at 65535. */
uint16_t sonar_ring_mm_from_echo_us(uint32_t echo_us);

/* One-way range (mm) to echo pulse width (us), rounded up. */
uint32_t sonar_ring_echo_us_from_mm(uint16_t range_mm);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_SONAR_RING_H */
