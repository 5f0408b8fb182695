/* Simulated HAL backend: a world in software instead of a board. Built for the
 * native environment (unit tests and the SIL) and for unit-test builds on every
 * target, so the same module tests run natively, under simavr and under QEMU;
 * the real avr/stm32 backends are exercised by the whole-firmware tests. */
#if (!defined(__AVR__) && !defined(__arm__)) || defined(PIO_UNIT_TESTING)

#include "hal_sim.h"
#include "../hal_clock_ms.h"

#include <string.h>

#define UART_PORTS 2u

typedef struct {
    uint8_t buf[SIM_UART_BUF];
    uint16_t head;
    uint16_t count;
} sim_fifo_t;

static struct {
    uint32_t now_us;
    hal_clock_ms_t clock_ms; /* hal_time_ms: counts on across now_us's wrap */
    hal_reset_cause_t reset_cause;
    hal_encoder_edge_fn encoder_fn;
    uint8_t encoder_count;
    uint8_t encoder_hall; /* bit i: encoder i is single-channel (Hall): B reads 0 */
    hal_echo_edge_fn echo_fn;
    uint8_t sonar_count;
    sim_trigger_fn trigger_fn;
    uint32_t trigger_count[HAL_SONAR_MAX];
    uint32_t last_trigger_us[HAL_SONAR_MAX];
    uint16_t echo_high; /* bit i: echo line i is high */
    uint16_t echo_held; /* bit i: echo line i held high (sim_sonar_echo_hold_high) */
    uint16_t servo_us[HAL_SERVO_MAX];
    uint8_t pwm_duty[HAL_PWM_MAX];
    bool pwm_reverse[HAL_PWM_MAX];
    sim_fifo_t tx[UART_PORTS];
    sim_fifo_t rx[UART_PORTS];
    uint8_t eeprom[SIM_EEPROM_SIZE];
    uint32_t eeprom_idle_calls; /* hal_eeprom_idle(): the application said the robot is at rest */
    uint32_t eeprom_write_us;      /* programming time of one byte (0: instant) */
    uint32_t eeprom_busy_until_us; /* hal_eeprom_busy() until this time */
    uint32_t eeprom_writes;        /* bytes written since sim_reset() */
    uint16_t eeprom_last_write_addr;
    uint32_t wdt_kicks;
    uint16_t wdt_timeout_ms;
    bool irq_masked;
} sim;

static uint16_t fifo_put(sim_fifo_t *f, const uint8_t *src, uint16_t len)
{
    uint16_t n = 0;
    while (n < len && f->count < SIM_UART_BUF) {
        f->buf[(uint16_t)((f->head + f->count) % SIM_UART_BUF)] = src[n++];
        f->count++;
    }
    return n;
}

static uint16_t fifo_take(sim_fifo_t *f, uint8_t *dst, uint16_t max)
{
    uint16_t n = 0;
    while (n < max && f->count > 0) {
        dst[n++] = f->buf[f->head];
        f->head = (uint16_t)((f->head + 1u) % SIM_UART_BUF);
        f->count--;
    }
    return n;
}

void sim_reset(void)
{
    memset(&sim, 0, sizeof sim);
    memset(sim.eeprom, 0xFF, sizeof sim.eeprom);
    for (uint8_t i = 0; i < HAL_SERVO_MAX; i++) {
        sim.servo_us[i] = 1500u;
    }
}

void hal_init(void) { /* state is set by sim_reset() */ }
bool hal_clock_from_crystal(void) { return true; } /* the world's clock is exact */
uint32_t hal_time_us(void) { return sim.now_us; }
uint32_t hal_time_ms(void) { return hal_clock_ms_update(&sim.clock_ms, sim.now_us); }
void hal_delay_us(uint16_t us) { sim.now_us += us; }
/* The world owns time in the simulation: idling is the caller's stepping, not ours. */
void hal_idle_until(uint32_t t_us) { (void)t_us; }

void sim_time_set_us(uint32_t t_us)
{
    sim.now_us = t_us;
    hal_clock_ms_start(&sim.clock_ms, t_us); /* a set time is absolute: milliseconds restart from it */
}
void sim_time_advance_us(uint32_t dt_us) { sim.now_us += dt_us; }
void sim_set_reset_cause(hal_reset_cause_t cause) { sim.reset_cause = cause; }

hal_irq_state_t hal_irq_save(void)
{
    hal_irq_state_t was = sim.irq_masked ? 1u : 0u;
    sim.irq_masked = true;
    return was;
}

void hal_irq_restore(hal_irq_state_t s) { sim.irq_masked = (s != 0u); }
bool sim_irq_masked(void) { return sim.irq_masked; }

void hal_uart_init(uint8_t port, uint32_t baud)
{
    (void)baud;
    if (port < UART_PORTS) {
        sim.tx[port].head = sim.tx[port].count = 0;
        sim.rx[port].head = sim.rx[port].count = 0;
    }
}

uint16_t hal_uart_write(uint8_t port, const uint8_t *data, uint16_t len)
{
    return port < UART_PORTS ? fifo_put(&sim.tx[port], data, len) : 0u;
}

uint16_t hal_uart_read(uint8_t port, uint8_t *data, uint16_t max)
{
    return port < UART_PORTS ? fifo_take(&sim.rx[port], data, max) : 0u;
}

uint16_t hal_uart_tx_space(uint8_t port)
{
    return port < UART_PORTS ? (uint16_t)(SIM_UART_BUF - sim.tx[port].count) : 0u;
}

uint16_t sim_uart_take_tx(uint8_t port, uint8_t *dst, uint16_t max)
{
    return port < UART_PORTS ? fifo_take(&sim.tx[port], dst, max) : 0u;
}

uint16_t sim_uart_put_rx(uint8_t port, const uint8_t *src, uint16_t len)
{
    return port < UART_PORTS ? fifo_put(&sim.rx[port], src, len) : 0u;
}

void hal_encoder_attach(uint8_t count, uint8_t hall_mask, hal_encoder_edge_fn fn)
{
    sim.encoder_count = count > HAL_ENCODER_MAX ? HAL_ENCODER_MAX : count;
    sim.encoder_hall = hall_mask;
    sim.encoder_fn = fn;
}

/* Every edge reaches the hook: no hardware counter to fold. */
void hal_encoder_poll(void) {}

/* The world sets both lines; a Hall wheel's B input is not read (hal.h), so the hook sees B = 0. */
void sim_encoder_edge(uint8_t idx, uint8_t ab)
{
    if (sim.encoder_fn != 0 && idx < sim.encoder_count) {
        if ((sim.encoder_hall & (1u << idx)) != 0u) {
            ab &= 2u;
        }
        sim.encoder_fn(idx, ab, sim.now_us);
    }
}

void hal_sonar_attach(uint8_t count, hal_echo_edge_fn fn)
{
    sim.sonar_count = count > HAL_SONAR_MAX ? HAL_SONAR_MAX : count;
    sim.echo_fn = fn;
}

void hal_sonar_poll(void) {} /* the hook runs at each sim_sonar_echo_edge() */

void hal_sonar_trigger(uint8_t idx)
{
    if (idx >= HAL_SONAR_MAX) {
        return;
    }
    sim.trigger_count[idx]++;
    sim.last_trigger_us[idx] = sim.now_us;
    if (sim.trigger_fn != 0) {
        sim.trigger_fn(idx, sim.now_us);
    }
}

void sim_sonar_on_trigger(sim_trigger_fn fn) { sim.trigger_fn = fn; }

/* The line takes the level; the hook hears it only if the line changes and a ring is attached (a
 * line already high at hal_sonar_attach() makes no edge, as on the boards). */
static void echo_line_set(uint8_t idx, uint8_t level)
{
    uint16_t bit = (uint16_t)(1u << idx);
    bool changed = ((sim.echo_high & bit) != 0u) != (level != 0u);
    sim.echo_high = (uint16_t)(level != 0u ? sim.echo_high | bit : sim.echo_high & ~bit);
    if (changed && sim.echo_fn != 0 && idx < sim.sonar_count) {
        sim.echo_fn(idx, level, sim.now_us);
    }
}

void sim_sonar_echo_edge(uint8_t idx, uint8_t level)
{
    if (idx >= HAL_SONAR_MAX || (sim.echo_held & (1u << idx)) != 0u) {
        return; /* a held line does not move */
    }
    if (sim.echo_fn != 0 && idx < sim.sonar_count) {
        sim.echo_fn(idx, level, sim.now_us);
    }
    sim.echo_high = (uint16_t)(level != 0u ? sim.echo_high | (1u << idx) : sim.echo_high & ~(1u << idx));
}

void sim_sonar_echo_hold_high(uint8_t idx, bool hold)
{
    if (idx >= HAL_SONAR_MAX) {
        return;
    }
    if (hold) {
        sim.echo_held = (uint16_t)(sim.echo_held | (1u << idx));
        echo_line_set(idx, 1u);
    } else {
        sim.echo_held = (uint16_t)(sim.echo_held & ~(1u << idx));
        echo_line_set(idx, 0u);
    }
}

uint32_t sim_sonar_trigger_count(uint8_t idx) { return idx < HAL_SONAR_MAX ? sim.trigger_count[idx] : 0u; }
uint32_t sim_sonar_last_trigger_us(uint8_t idx) { return idx < HAL_SONAR_MAX ? sim.last_trigger_us[idx] : 0u; }

void hal_servo_write_us(uint8_t channel, uint16_t pulse_us)
{
    if (channel < HAL_SERVO_MAX) {
        sim.servo_us[channel] = pulse_us;
    }
}

void hal_pwm_write_duty(uint8_t channel, uint8_t duty, bool reverse)
{
    if (channel < HAL_PWM_MAX) {
        sim.pwm_duty[channel] = duty;
        sim.pwm_reverse[channel] = reverse;
    }
}

uint16_t sim_servo_us(uint8_t channel) { return channel < HAL_SERVO_MAX ? sim.servo_us[channel] : 0u; }
uint8_t sim_pwm_duty(uint8_t channel) { return channel < HAL_PWM_MAX ? sim.pwm_duty[channel] : 0u; }
bool sim_pwm_reverse(uint8_t channel) { return channel < HAL_PWM_MAX && sim.pwm_reverse[channel]; }

uint16_t hal_eeprom_size(void) { return (uint16_t)SIM_EEPROM_SIZE; }

void hal_eeprom_read(uint16_t addr, void *dst, uint16_t len)
{
    uint8_t *d = (uint8_t *)dst;
    for (uint16_t i = 0; i < len; i++) {
        uint32_t a = (uint32_t)addr + i;
        d[i] = a < SIM_EEPROM_SIZE ? sim.eeprom[a] : 0xFFu;
    }
}

bool hal_eeprom_busy(void) { return (int32_t)(sim.eeprom_busy_until_us - sim.now_us) > 0; }

bool hal_eeprom_write_byte(uint16_t addr, uint8_t value)
{
    sim.eeprom_writes++;
    sim.eeprom_last_write_addr = addr;
    sim.eeprom_busy_until_us = sim.now_us + sim.eeprom_write_us;
    if (addr >= SIM_EEPROM_SIZE) {
        return false;
    }
    sim.eeprom[addr] = value;
    return true;
}

void sim_eeprom_set_write_us(uint32_t us) { sim.eeprom_write_us = us; }
void sim_eeprom_settle(void) { sim.eeprom_busy_until_us = sim.now_us; }
uint32_t sim_eeprom_writes(void) { return sim.eeprom_writes; }
uint16_t sim_eeprom_last_write_addr(void) { return sim.eeprom_last_write_addr; }

uint8_t *sim_eeprom_bytes(void) { return sim.eeprom; }

void hal_eeprom_idle(void) { sim.eeprom_idle_calls++; }
uint32_t sim_eeprom_idle_calls(void) { return sim.eeprom_idle_calls; }

void hal_watchdog_start(uint16_t timeout_ms) { sim.wdt_timeout_ms = timeout_ms; }
void hal_watchdog_kick(void) { sim.wdt_kicks++; }
hal_reset_cause_t hal_reset_cause(void) { return sim.reset_cause; }
uint32_t sim_watchdog_kicks(void) { return sim.wdt_kicks; }
uint16_t sim_watchdog_timeout_ms(void) { return sim.wdt_timeout_ms; }

#endif /* native build, or any unit-test build */
