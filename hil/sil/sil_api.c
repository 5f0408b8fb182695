/* AgNav native SIL: see sil_api.h. Built with the firmware into libagnav_sil.so. */
#include "sil_api.h"
#include "sil_events.h"

#include <string.h>

#include "hal.h"
#include "params.h"
#include "sim/hal_sim.h"

/* The firmware's EEPROM map (params.h). */
#ifndef SIL_EEPROM_PARAMS_ADDR
#define SIL_EEPROM_PARAMS_ADDR PARAMS_EEPROM_ADDR
#endif

void agnav_setup(void);
void agnav_loop_once(void);

enum { EV_ENCODER = 0, EV_ECHO = 1 };


static struct {
    uint64_t now_us;
    uint32_t tick_us;
    int stop_on_trigger;
    uint64_t loop_passes;
    uint64_t ev_seq;
    uint32_t ev_n;
    uint32_t late;
    uint32_t trig_head, trig_n;
    uint8_t trig_idx[SIL_TRIGGER_MAX];
    uint64_t trig_t[SIL_TRIGGER_MAX];
    uint32_t trig_new; /* triggers since the current loop pass began */
} S;

static sil_event_t s_heap[SIL_EVENT_MAX];

/* ---- event min-heap on (t_us, seq) ------------------------------------------ */
static int ev_push(uint8_t kind, uint8_t idx, uint8_t val, uint64_t t_us)
{
    return sil_ev_push(s_heap, SIL_EVENT_MAX, &S.ev_n, &S.ev_seq, kind, idx, val, t_us);
}

static sil_event_t ev_pop(void) { return sil_ev_pop(s_heap, &S.ev_n); }

/* ---- hooks --------------------------------------------------------------------- */
static void on_trigger(uint8_t idx, uint32_t t_us)
{
    (void)t_us; /* same as S.now_us's low bits; keep the 64-bit time */
    if (S.trig_n < SIL_TRIGGER_MAX) {
        uint32_t k = (S.trig_head + S.trig_n) % SIL_TRIGGER_MAX;
        S.trig_idx[k] = idx;
        S.trig_t[k] = S.now_us;
        S.trig_n++;
    }
    S.trig_new++;
}

static void set_time(uint64_t t)
{
    S.now_us = t;
    sim_time_set_us((uint32_t)t);
}

/* ---- life cycle ------------------------------------------------------------------ */
uint32_t sil_api_version(void) { return SIL_API_VERSION; }

void sil_init(void)
{
    memset(&S, 0, sizeof S);
    S.tick_us = 100u;
    S.stop_on_trigger = 1;
    sim_reset();
    sim_sonar_on_trigger(on_trigger);
}

void sil_boot(void)
{
    set_time(S.now_us);
    agnav_setup();
}

void sil_reset(void)
{
    sil_init();
    sil_boot();
}

void sil_reboot(void)
{
    static uint8_t keep[SIM_EEPROM_SIZE];
    memcpy(keep, sim_eeprom_bytes(), SIM_EEPROM_SIZE);
    sil_init();
    memcpy(sim_eeprom_bytes(), keep, SIM_EEPROM_SIZE);
    sil_boot();
}

/* ---- time ------------------------------------------------------------------------------ */
uint64_t sil_time_us(void) { return S.now_us; }

void sil_set_tick_us(uint32_t tick_us)
{
    S.tick_us = tick_us < 1u ? 1u : (tick_us > 10000u ? 10000u : tick_us);
}

void sil_set_stop_on_trigger(int on) { S.stop_on_trigger = on != 0; }
uint64_t sil_loop_passes(void) { return S.loop_passes; }

static void deliver_due(void)
{
    while (S.ev_n > 0u && s_heap[0].t_us <= S.now_us) {
        sil_event_t e = ev_pop();
        if (e.t_us < S.now_us) {
            S.late++;
        }
        if (e.kind == EV_ENCODER) {
            sim_encoder_edge(e.idx, e.val);
        } else {
            sim_sonar_echo_edge(e.idx, e.val);
        }
    }
}

uint64_t sil_step_to(uint64_t target)
{
    deliver_due(); /* anything queued for "now" or earlier */
    while (S.now_us < target) {
        uint64_t next = S.now_us + S.tick_us;
        if (next > target) {
            next = target;
        }
        if (S.ev_n > 0u && s_heap[0].t_us < next) {
            next = s_heap[0].t_us > S.now_us ? s_heap[0].t_us : S.now_us + 1u;
        }
        set_time(next);
        deliver_due();
        S.trig_new = 0u;
        agnav_loop_once();
        S.loop_passes++;
        if (S.stop_on_trigger && S.trig_new != 0u) {
            break;
        }
    }
    return S.now_us;
}

uint32_t sil_step(uint32_t dt_us)
{
    uint64_t t0 = S.now_us;
    return (uint32_t)(sil_step_to(t0 + dt_us) - t0);
}

/* ---- serial --------------------------------------------------------------------------------- */
uint32_t sil_uart_write(const uint8_t *data, uint32_t len)
{
    uint32_t done = 0u;
    while (done < len) {
        uint16_t chunk = (uint16_t)(len - done > 0xFFFFu ? 0xFFFFu : len - done);
        uint16_t n = sim_uart_put_rx(HAL_UART_LINK, data + done, chunk);
        done += n;
        if (n < chunk) {
            break;
        }
    }
    return done;
}

uint32_t sil_uart_read(uint8_t *buf, uint32_t max)
{
    uint32_t done = 0u;
    while (done < max) {
        uint16_t chunk = (uint16_t)(max - done > 0xFFFFu ? 0xFFFFu : max - done);
        uint16_t n = sim_uart_take_tx(HAL_UART_LINK, buf + done, chunk);
        done += n;
        if (n < chunk) {
            break;
        }
    }
    return done;
}

/* ---- encoders and sonar ------------------------------------------------------------------- */
void sil_encoder_edge(uint8_t idx, uint8_t ab) { sim_encoder_edge(idx, ab); }

uint32_t sil_queue_encoder_edges(uint8_t idx, const uint64_t *t_us, const uint8_t *ab, uint32_t n)
{
    uint32_t k = 0u;
    for (; k < n; k++) {
        if (!ev_push(EV_ENCODER, idx, ab[k], t_us[k])) {
            break;
        }
    }
    return k;
}

int sil_queue_echo(uint8_t idx, uint64_t t_us, uint8_t level)
{
    return ev_push(EV_ECHO, idx, level != 0u, t_us);
}

uint32_t sil_take_triggers(uint8_t *idx, uint64_t *t_us, uint32_t max)
{
    uint32_t k = 0u;
    while (k < max && S.trig_n > 0u) {
        idx[k] = S.trig_idx[S.trig_head];
        t_us[k] = S.trig_t[S.trig_head];
        S.trig_head = (S.trig_head + 1u) % SIL_TRIGGER_MAX;
        S.trig_n--;
        k++;
    }
    return k;
}

uint32_t sil_sonar_trigger_count(uint8_t idx) { return sim_sonar_trigger_count(idx); }
void sil_sonar_echo_edge(uint8_t idx, uint8_t level) { sim_sonar_echo_edge(idx, level); }
uint32_t sil_pending_events(void) { return S.ev_n; }
uint32_t sil_late_events(void) { return S.late; }

/* ---- actuators ------------------------------------------------------------------------------ */
void sil_outputs(sil_outputs_t *out)
{
    memset(out, 0, sizeof *out);
    for (uint8_t i = 0; i < 2u; i++) {
        out->servo_us[i] = sim_servo_us(i);
        out->duty[i] = sim_pwm_duty(i);
        out->reverse[i] = sim_pwm_reverse(i) ? 1u : 0u;
    }
    out->wdt_kicks = sim_watchdog_kicks();
    out->wdt_timeout_ms = sim_watchdog_timeout_ms();
}

uint16_t sil_servo_us(uint8_t channel) { return sim_servo_us(channel); }
uint8_t sil_pwm_duty(uint8_t channel) { return sim_pwm_duty(channel); }
uint8_t sil_pwm_reverse(uint8_t channel) { return sim_pwm_reverse(channel) ? 1u : 0u; }

/* ---- parameters and EEPROM -------------------------------------------------------------------- */
int sil_param_set(const char *name, int32_t value)
{
    int16_t i = params_find(name);
    if (i < 0) {
        return PARAMS_UNKNOWN;
    }
    return (int)params_set((uint16_t)i, value);
}

int sil_param_get(const char *name, int32_t *out)
{
    int16_t i = params_find(name);
    if (i < 0) {
        return -1;
    }
    *out = params_get((uint16_t)i);
    return 0;
}

int sil_param_save(void) { return (int)params_save(SIL_EEPROM_PARAMS_ADDR); }
uint32_t sil_eeprom_size(void) { return hal_eeprom_size(); }
void sil_eeprom_read(uint32_t addr, uint8_t *dst, uint32_t len) { hal_eeprom_read((uint16_t)addr, dst, (uint16_t)len); }
void sil_eeprom_write(uint32_t addr, const uint8_t *src, uint32_t len) { hal_eeprom_write((uint16_t)addr, src, (uint16_t)len); }
