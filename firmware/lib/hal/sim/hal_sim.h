/*
 * Test and SIL side of the simulated HAL backend: the world (a unit test or
 * the SIL harness) owns time and drives the pins through these calls.
 */
#ifndef AGNAV_HAL_SIM_H
#define AGNAV_HAL_SIM_H

#include "../hal.h"

#ifdef __cplusplus
extern "C" {
#endif

#if defined(__AVR__)
/* Unit tests under simavr share the ATmega2560's 8 KB of RAM with the sim backend: room for the
 * EEPROM map up to the calibration copy (storage.h), not the chip's whole 4 KB, and for two
 * signed MAVLink frames (2 x 69 B) in each UART queue. */
#define SIM_EEPROM_SIZE 1280u
#define SIM_UART_BUF 160u
#else
#define SIM_EEPROM_SIZE 4096u
#define SIM_UART_BUF 4096u
#endif

void sim_reset(void);                    /* power-on state: time 0, buffers empty, EEPROM erased (0xFF) */
void sim_time_set_us(uint32_t t_us);
void sim_time_advance_us(uint32_t dt_us);
void sim_set_reset_cause(hal_reset_cause_t cause);

/* Inject an encoder edge at the current simulated time (calls the attached hook; for an encoder
 * attached as Hall, B reaches the hook as 0). */
void sim_encoder_edge(uint8_t idx, uint8_t ab);
/* Inject an echo edge on sonar idx at the current simulated time (ignored while the line is held). */
void sim_sonar_echo_edge(uint8_t idx, uint8_t level);
/* Hold the echo line of sonar idx high (hold = true) or let it go low (false), at the current
 * simulated time: an unplugged sensor on a pulled-up pin, or an echo output stuck high. The hook
 * hears a rising (falling) edge if the line was low (high) and a ring is attached; a line held
 * before hal_sonar_attach() makes no edge. While held, sim_sonar_echo_edge() on idx does nothing. */
void sim_sonar_echo_hold_high(uint8_t idx, bool hold);
/* Number of trigger pulses emitted on sonar idx since reset, and time of the last one. */
uint32_t sim_sonar_trigger_count(uint8_t idx);
uint32_t sim_sonar_last_trigger_us(uint8_t idx);
/* Optional hook called on every trigger (the SIL uses it to schedule echoes). */
typedef void (*sim_trigger_fn)(uint8_t idx, uint32_t t_us);
void sim_sonar_on_trigger(sim_trigger_fn fn);

uint16_t sim_servo_us(uint8_t channel);
uint8_t sim_pwm_duty(uint8_t channel);
bool sim_pwm_reverse(uint8_t channel);

/* Bytes the firmware wrote to a UART (drained by the caller). */
uint16_t sim_uart_take_tx(uint8_t port, uint8_t *dst, uint16_t max);
/* Bytes for the firmware to read. Returns how many fitted. */
uint16_t sim_uart_put_rx(uint8_t port, const uint8_t *src, uint16_t len);

uint8_t *sim_eeprom_bytes(void);          /* direct access for corruption tests */
uint32_t sim_eeprom_idle_calls(void);     /* hal_eeprom_idle() calls since sim_reset() */
void sim_eeprom_set_write_us(uint32_t us);  /* each byte keeps hal_eeprom_busy() true this long (0 after reset) */
void sim_eeprom_settle(void);             /* the byte in flight is done (for writes before the clock runs) */
uint32_t sim_eeprom_writes(void);         /* hal_eeprom_write_byte() calls since sim_reset() */
uint16_t sim_eeprom_last_write_addr(void); /* address of the latest of them */
uint32_t sim_watchdog_kicks(void);
uint16_t sim_watchdog_timeout_ms(void);
bool sim_irq_masked(void);

#ifdef __cplusplus
}
#endif

#endif
