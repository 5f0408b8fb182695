/*
 * AgNav native software-in-the-loop (SIL): the real firmware (firmware/src/main.c
 * and firmware/lib/<module>/, unchanged) built for the PC against the simulated
 * HAL (firmware/lib/hal/sim), with a small C API for a world simulator.
 *
 * Time. The SIL owns a 64-bit microsecond clock; the firmware sees its low 32
 * bits through hal_time_us() (so a run longer than ~71.6 min exercises the wrap).
 * sil_step() advances it in ticks of at most sil_set_tick_us() (default 100 us),
 * calling agnav_loop_once() after every advance, i.e. the firmware's main loop
 * runs at >= 10 kHz and the static scheduler runs its tasks at their own rates.
 *
 * Timed events. Encoder edges and sonar echo edges are queued with an absolute
 * time (sil_queue_encoder_edges, sil_queue_echo); sil_step() stops the clock at
 * each event's microsecond, delivers it through the HAL hook (the "interrupt")
 * and runs one loop pass. Events queued in the past are delivered at once
 * (counted in sil_late_events()). Ties keep queueing order.
 *
 * Sonar. Each hal_sonar_trigger() of the firmware is recorded (sonar index and
 * time). With sil_set_stop_on_trigger(1) (default) sil_step() returns right
 * after the loop pass that fired a trigger, so the caller can compute the echo
 * with the world as it is then and queue the rise/fall edges before time moves on.
 *
 * Life cycle: sil_init() is a power-on with an erased EEPROM that does not boot;
 * sil_boot() runs agnav_setup(); sil_reset() = both. sil_reboot() keeps the
 * EEPROM (stored parameters and calibration) and boots again. The firmware's
 * file-scope state outside agnav_setup() is not cleared by a reboot (main.c's
 * statics), so configure parameters before the first sil_step() and reboot
 * then, or load a fresh copy of the library (the Python binding does) for a
 * pristine power-on.
 */
#ifndef AGNAV_SIL_API_H
#define AGNAV_SIL_API_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SIL_API_VERSION 2u
#define SIL_EVENT_MAX 65536u   /* queued encoder/echo edges */
#define SIL_TRIGGER_MAX 256u   /* sonar triggers not yet taken */

typedef struct {
    uint16_t servo_us[2];  /* HAL_SERVO_STEER, HAL_SERVO_THROTTLE pulse widths */
    uint8_t duty[2];       /* H-bridge duty, 0 left, 1 right */
    uint8_t reverse[2];    /* H-bridge direction lines (1 = reverse) */
    uint32_t wdt_kicks;    /* hal_watchdog_kick() calls since power-on */
    uint16_t wdt_timeout_ms;
    uint16_t reserved;
} sil_outputs_t;

uint32_t sil_api_version(void);

/* ---- life cycle ------------------------------------------------------- */
void sil_init(void);
void sil_boot(void);
void sil_reset(void);
void sil_reboot(void);

/* ---- time --------------------------------------------------------------- */
uint64_t sil_time_us(void);
void sil_set_tick_us(uint32_t tick_us);        /* 1..10000, default 100 */
void sil_set_stop_on_trigger(int on);          /* default 1 */
/* Advance up to dt_us; returns the microseconds actually advanced (less than
 * dt_us only when it stopped after a sonar trigger). */
uint32_t sil_step(uint32_t dt_us);
/* Advance to an absolute time (same early stop); returns the time reached. */
uint64_t sil_step_to(uint64_t t_us);
uint64_t sil_loop_passes(void);                /* agnav_loop_once() calls since sil_init */

/* ---- serial link (HAL_UART_LINK) ---------------------------------------- */
/* Bytes for the firmware (what the radio received); returns how many fitted. */
uint32_t sil_uart_write(const uint8_t *data, uint32_t len);
/* Bytes the firmware sent (drained); returns the count. */
uint32_t sil_uart_read(uint8_t *buf, uint32_t max);

/* ---- encoders ----------------------------------------------------------- */
/* One edge now: ab = (A << 1) | B, levels after the edge. */
void sil_encoder_edge(uint8_t idx, uint8_t ab);
/* n timed edges of encoder idx (t_us absolute, non-decreasing preferred).
 * Returns how many were queued (the queue holds SIL_EVENT_MAX events). */
uint32_t sil_queue_encoder_edges(uint8_t idx, const uint64_t *t_us, const uint8_t *ab, uint32_t n);

/* ---- sonar -------------------------------------------------------------- */
/* Echo line edge of sonar idx (level 1 rise, 0 fall) at absolute t_us; 0/1. */
int sil_queue_echo(uint8_t idx, uint64_t t_us, uint8_t level);
/* Triggers fired since the last call, oldest first; returns the count. */
uint32_t sil_take_triggers(uint8_t *idx, uint64_t *t_us, uint32_t max);
uint32_t sil_sonar_trigger_count(uint8_t idx);
void sil_sonar_echo_edge(uint8_t idx, uint8_t level); /* one edge now */

uint32_t sil_pending_events(void);
uint32_t sil_late_events(void);

/* ---- actuators ------------------------------------------------------------ */
void sil_outputs(sil_outputs_t *out);
uint16_t sil_servo_us(uint8_t channel);
uint8_t sil_pwm_duty(uint8_t channel);
uint8_t sil_pwm_reverse(uint8_t channel);

/* ---- parameters and EEPROM ------------------------------------------------ */
/* Set a parameter by name in RAM (after sil_boot; takes effect now for values
 * read every tick, at the next boot for the robot profile); 0 ok, <0 params_result_t. */
int sil_param_set(const char *name, int32_t value);
/* Read a parameter; 0 ok (value in *out), -1 unknown. */
int sil_param_get(const char *name, int32_t *out);
/* Store all parameters to EEPROM where the firmware loads them at boot; 0 ok. */
int sil_param_save(void);
uint32_t sil_eeprom_size(void);
void sil_eeprom_read(uint32_t addr, uint8_t *dst, uint32_t len);
void sil_eeprom_write(uint32_t addr, const uint8_t *src, uint32_t len);
/* Native backend only: how often the firmware called hal_eeprom_idle() (the robot at rest) since reset. */
uint32_t sil_eeprom_idle_calls(void);
uint32_t sil_eeprom_writes(void); /* native: EEPROM bytes programmed since reset */

/* =====================================================================================
 * FAULT INJECTION (SIL API version 2): hooks for the fault table (`make faults`).
 * Every hook acts at once and stays until cleared (mode SIL_FAULT_NONE); none of them
 * touches the firmware's code paths: they change what the "hardware" delivers.
 * docs/safety.md lists the firmware's detection and reaction for each.
 *
 *   Encoders   sil_fault_encoder(idx, mode)
 *     SIL_ENC_STUCK         edges of encoder idx are swallowed: the count freezes while
 *                           the (simulated) wheel turns (broken magnet, slipping coupling).
 *     SIL_ENC_DISCONNECTED  both lines float high (pull-ups): one jump to ab = 3 now,
 *                           then no edges (unplugged connector).
 *     SIL_ENC_NOISE         every edge arrives as an illegal jump (both lines at once):
 *                           an illegal-transition storm (EMI, a broken wire touching).
 *   Sonars     sil_fault_sonar(idx, mode)
 *     SIL_SONAR_TIMEOUT     the echo line never rises after a trigger (dead or unplugged
 *                           sensor): the world's echo edges for idx are swallowed.
 *     SIL_SONAR_ZERO        an echo pulse of SIL_SONAR_ZERO_ECHO_US starts
 *                           SIL_SONAR_ZERO_DELAY_US after every trigger (reads ~0 mm:
 *                           a shorted transducer / ringing); world edges swallowed.
 *                           Either fault lets a world pulse already high when it begins
 *                           end on time (its falling edge is delivered): the line is never
 *                           left high, which would be a third fault (output stuck high).
 *   EEPROM     sil_eeprom_record(which, &addr, &len) locates a record (SIL_REC_*);
 *              sil_eeprom_corrupt(addr, len, xor_mask) flips bits there; the firmware
 *              sees it at its next boot (sil_reboot() or sil_fault_reset()).
 *   Resets     sil_fault_reset(cause): a core reset NOW with reset cause `cause`
 *              (SIL_RESET_*: the values of hal_reset_cause_t). The world goes on: the SIL
 *              clock, queued events and the EEPROM are kept; the firmware's RAM state
 *              and outputs start afresh (outputs neutral) and agnav_setup() runs.
 *              Native: the firmware's clock continues (it only uses differences);
 *              simavr: a real core reset with MCUSR set to WDRF / BORF / EXTRF / PORF.
 *   Watchdog   native: modelled. After hal_watchdog_start(), a gap between two
 *              hal_watchdog_kick() calls longer than the timeout is a watchdog reset
 *              (as sil_fault_reset(SIL_RESET_WATCHDOG)); simavr: the real watchdog.
 *              sil_resets() counts resets of either kind since power-on;
 *              sil_kick_gap_max_us() is the longest gap between two kicks (the control
 *              task kicks every tick, so this is its worst period) since the last call.
 *   ISR bursts sil_isr_burst(idx, n, period_us) queues n legal quadrature edges of
 *              encoder idx, the first period_us from now (at period_us intervals).
 *              sil_set_isr_cost_us(us) (native only; simavr runs the real ISR cycles)
 *              makes every delivered edge (encoder or echo) take us of CPU time, during
 *              which the main loop cannot run, as an interrupt would.
 *
 * The simavr backend (hil/simavr/avr_sil.c) implements all of these with the same
 * semantics except sil_set_isr_cost_us (ignored: the real ISR costs real cycles).
 * ===================================================================================== */
#define SIL_FAULT_NONE 0
#define SIL_ENC_STUCK 1
#define SIL_ENC_DISCONNECTED 2
#define SIL_ENC_NOISE 3
#define SIL_SONAR_TIMEOUT 1
#define SIL_SONAR_ZERO 2
#define SIL_SONAR_ZERO_DELAY_US 300u
#define SIL_SONAR_ZERO_ECHO_US 60u /* ~10 mm */

#define SIL_REC_CALIB 0   /* calibration tables (calib.h) */
#define SIL_REC_PARAMS 1  /* parameter record (params.h) */
#define SIL_REC_SIGNING 2 /* MAVLink signing key record (signing.h) */
#define SIL_REC_SIGNING_TS 3 /* signing timestamp ring (signing.h) */
#define SIL_REC_CALIB_COPY 4 /* the copy slots lib/storage writes before each main slot */
#define SIL_REC_PARAMS_COPY 5
#define SIL_REC_SIGNING_COPY 6

#define SIL_RESET_POWER_ON 0
#define SIL_RESET_WATCHDOG 1
#define SIL_RESET_EXTERNAL 2
#define SIL_RESET_BROWN_OUT 3

/* 0 ok, -1 bad index or mode. */
int sil_fault_encoder(uint8_t idx, int mode);
int sil_fault_sonar(uint8_t idx, int mode);
/* 0 ok (addr, len filled), -1 unknown record. */
int sil_eeprom_record(int which, uint32_t *addr, uint32_t *len);
void sil_eeprom_corrupt(uint32_t addr, uint32_t len, uint8_t xor_mask);
void sil_fault_reset(int cause);
uint32_t sil_resets(void);
uint32_t sil_kick_gap_max_us(void);
uint32_t sil_isr_burst(uint8_t idx, uint32_t n, uint32_t period_us);
void sil_set_isr_cost_us(uint32_t us);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_SIL_API_H */
