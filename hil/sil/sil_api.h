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

#define SIL_API_VERSION 1u
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

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_SIL_API_H */
