/*
 * AgNav hardware abstraction layer: the one interface every firmware module
 * talks to. Three backends implement it:
 *   avr/   ATmega2560 timers, pin-change interrupts, USART, EEPROM, watchdog
 *   stm32/ STM32F405 registers: clock tree, SysTick, USART1, GPIO, EXTI, timer encoder mode,
 *          TIM9..11 PWM, IWDG (board.h: Olimex STM32-H405)
 *   sim/   driven by unit tests and by the software-in-the-loop harness
 *
 * Devices are addressed by logical index (encoder 0..3, sonar 0..11, servo
 * channel 0..1); pin numbers only live in each backend's board.h.
 * Interrupt hooks only timestamp and count: the callbacks registered here are
 * called from interrupt context (the echo hook may be called from hal_sonar_poll
 * instead) and must stay short.
 */
#ifndef AGNAV_HAL_H
#define AGNAV_HAL_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- life cycle and time ---------------------------------------------- */
void hal_init(void);
/* Monotonic microseconds since boot; wraps every 2^32 us (~71.6 min).
 * Compare times with (int32_t)(a - b), never with a < b. */
uint32_t hal_time_us(void);
uint32_t hal_time_ms(void);
/* True when the core clock comes from the board's crystal; false when the backend runs from an
 * internal RC oscillator because the crystal did not start (STM32: HSI, +-1 % at 25 degC, about
 * +-4 % from -10 to 85 degC, DS8626 HSI oscillator characteristics; serial bit rates and every
 * timing drift with it).
 * Backends without such a fallback (avr, sim) return true. Valid after hal_init(). */
bool hal_clock_from_crystal(void);
/* Busy-wait, used only for the 10 us sonar trigger pulse. */
void hal_delay_us(uint16_t us);
/* Sleep until about t_us (hal_time_us() clock) or the next interrupt, whichever comes
 * first; returns at once when t_us is not in the future. The main loop calls it when no
 * task is due: it saves power on the board and lets simulators skip idle cycles. */
void hal_idle_until(uint32_t t_us);

/* ---- critical sections ------------------------------------------------ */
#if defined(__AVR__)
typedef uint8_t hal_irq_state_t;
#else
typedef uint32_t hal_irq_state_t;
#endif
hal_irq_state_t hal_irq_save(void);     /* mask interrupts, return previous state */
void hal_irq_restore(hal_irq_state_t s); /* restore what hal_irq_save returned */

/* ---- serial ----------------------------------------------------------- */
#define HAL_UART_LINK 0u   /* telemetry radio (XBee) or USB serial */
#define HAL_UART_DEBUG 1u  /* test output under simavr / QEMU */
void hal_uart_init(uint8_t port, uint32_t baud);
/* Queue up to len bytes; returns how many were accepted (never blocks). */
uint16_t hal_uart_write(uint8_t port, const uint8_t *data, uint16_t len);
/* Copy up to max received bytes into data; returns the count. */
uint16_t hal_uart_read(uint8_t port, uint8_t *data, uint16_t max);
uint16_t hal_uart_tx_space(uint8_t port);

/* ---- wheel encoders --------------------------------------------------- */
#define HAL_ENCODER_MAX 4u
/* Called from interrupt context on every edge of channel A or B of encoder
 * idx. ab = (A << 1) | B, the levels just after the edge; t_us = hal_time_us().
 * In single-channel (Hall) mode B reads as 0. */
typedef void (*hal_encoder_edge_fn)(uint8_t idx, uint8_t ab, uint32_t t_us);
/* Encoders 0..count-1; bit i of hall_mask set: encoder i is a single-channel (Hall) sensor on A,
 * its edges reach fn with B = 0 (the B input is not pulled up or sampled); clear: A/B quadrature.
 * A backend may count quadrature encoders in hardware instead of calling fn per edge (STM32: the
 * timers' encoder mode); hal_encoder_poll() then brings their counts into the interrupt record. */
void hal_encoder_attach(uint8_t count, uint8_t hall_mask, hal_encoder_edge_fn fn);
/* Loop context: fold what hardware counters counted since the last call into the encoder interrupt
 * record (encoder/encoder_isr.h: raw-forward / raw-backward counts, stamped with the time of this
 * call), so the loop side reads them like edges from fn. Nothing to do where every edge goes
 * through fn or the AVR vector (avr, sim). encoder_update() calls it first; call it at least every
 * 32767 counts of a wheel (the 16-bit counter's half range). */
void hal_encoder_poll(void);

/* ---- sonar ring (trigger/echo, HC-SR04 / SRF05 class) ----------------- */
#define HAL_SONAR_MAX 12u
/* Called on each edge of the echo line of sonar idx, in edge order;
 * level = 1 rising (echo started), 0 falling (echo ended), t_us = hal_time_us() of the edge.
 * Either from interrupt context (sim, stm32) or, where the interrupt only queues
 * (lines, timestamp) records (avr), from hal_sonar_poll() in loop context: the hook must
 * work in both. */
typedef void (*hal_echo_edge_fn)(uint8_t idx, uint8_t level, uint32_t t_us);
void hal_sonar_attach(uint8_t count, hal_echo_edge_fn fn);
/* Loop context: deliver the echo edges queued since the last call to the hook (avr);
 * nothing to do on backends that call the hook from the interrupt. Call it before
 * looking at echo results, at least every 100 ms. */
void hal_sonar_poll(void);
/* Emit the >= 10 us trigger pulse on sonar idx. */
void hal_sonar_trigger(uint8_t idx);

/* ---- actuators -------------------------------------------------------- */
#define HAL_SERVO_STEER 0u  /* steering servo, 1000..2000 us */
#define HAL_SERVO_THROTTLE 1u  /* ESC, 1000..2000 us, 1500 neutral */
#define HAL_SERVO_MAX 2u
void hal_servo_write_us(uint8_t channel, uint16_t pulse_us);
/* 8-bit duty for an H-bridge (differential drive), channel 0 left, 1 right;
 * reverse selects the direction line. */
#define HAL_PWM_MAX 2u
void hal_pwm_write_duty(uint8_t channel, uint8_t duty, bool reverse);

/* ---- non-volatile storage --------------------------------------------- */
/* Writes never wait: hal_eeprom_write_byte() starts programming one byte and returns, and
 * hal_eeprom_busy() is true until the store can take the next byte or be read (AVR: EEPE, 3.3 ms a
 * byte; STM32: the active flash sector is full and moves to the other one only in hal_eeprom_idle(),
 * at rest; sim: the time set with sim_eeprom_set_write_us()). Reading while busy waits for the byte
 * in flight on the AVR. lib/storage writes the records through these, a byte per loop pass. */
uint16_t hal_eeprom_size(void);
bool hal_eeprom_busy(void);
void hal_eeprom_read(uint16_t addr, void *dst, uint16_t len);
/* Start writing one byte; false when it cannot be stored (beyond the size, flash failed). Call only
 * when hal_eeprom_busy() is false. */
bool hal_eeprom_write_byte(uint16_t addr, uint8_t value);
/* Called by the application about once a second while the robot is at rest (nothing commanded, wheels
 * still): storage upkeep whose stall would matter while driving (the STM32 backend moves its flash
 * EEPROM to the other sector when the active one is half full or full; others do nothing). */
void hal_eeprom_idle(void);

/* ---- watchdog and reset cause ----------------------------------------- */
typedef enum {
    HAL_RESET_POWER_ON = 0,
    HAL_RESET_WATCHDOG = 1,
    HAL_RESET_EXTERNAL = 2,
    HAL_RESET_BROWN_OUT = 3,
    HAL_RESET_OTHER = 4
} hal_reset_cause_t;
void hal_watchdog_start(uint16_t timeout_ms);
void hal_watchdog_kick(void);
hal_reset_cause_t hal_reset_cause(void);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_HAL_H */
