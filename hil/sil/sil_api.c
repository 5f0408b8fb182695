/* AgNav native SIL: see sil_api.h. Built with the firmware into libagnav_sil.so. */
#include "sil_api.h"
#include "sil_events.h"

#include <string.h>

#include "calib.h"
#include "hal.h"
#include "params.h"
#include "signing.h"
#include "sim/hal_sim.h"
#include "storage.h"

#include "sil_eeprom_map.h" /* after the firmware headers: checked against them */

/* Programming time of one EEPROM byte in the native SIL: the ATmega2560's (datasheet table 8-2:
 * 3.3 ms), so a save takes as long as on the board and the control tick is measured during it. */
#define SIL_EEPROM_WRITE_US 3300u

void agnav_setup(void);
void agnav_loop_once(void);



static struct {
    uint64_t now_us;
    uint32_t tick_us;
    int stop_on_trigger;
    uint64_t loop_passes;
    uint64_t ev_seq;
    uint32_t ev_n;
    uint32_t late;
    sil_trigger_queue_t trig;
    uint32_t trig_new; /* triggers since the current loop pass began */
    /* fault injection (sil_api.h) */
    uint8_t enc_fault[HAL_ENCODER_MAX];
    uint8_t enc_ab[HAL_ENCODER_MAX]; /* line levels last delivered to the firmware */
    uint8_t sonar_fault[HAL_SONAR_MAX];
    uint16_t world_echo_high; /* bit i: echo line i is high on a pulse of the world's (not an injected one) */
    uint32_t isr_cost_us;
    uint32_t resets;
    uint32_t wdt_kicks_seen;
    uint64_t last_kick_us;
    uint32_t kick_gap_max_us;
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
    (void)sil_trig_push(&S.trig, idx, S.now_us);
    S.trig_new++;
    if (idx < HAL_SONAR_MAX && S.sonar_fault[idx] == SIL_SONAR_ZERO) {
        uint64_t rise = S.now_us + SIL_SONAR_ZERO_DELAY_US;
        (void)ev_push(SIL_EV_ECHO_FAULT, idx, 1u, rise);
        (void)ev_push(SIL_EV_ECHO_FAULT, idx, 0u, rise + SIL_SONAR_ZERO_ECHO_US);
    }
}

/* What the encoder lines do under an injected fault; the firmware's ISR hook sees the result. */
static void encoder_deliver(uint8_t idx, uint8_t ab)
{
    if (idx >= HAL_ENCODER_MAX) {
        return;
    }
    switch (S.enc_fault[idx]) {
    case SIL_ENC_STUCK:
    case SIL_ENC_DISCONNECTED:
        return;
    case SIL_ENC_NOISE:
        ab = (uint8_t)(S.enc_ab[idx] ^ 3u); /* both lines at once: illegal */
        break;
    default:
        break;
    }
    S.enc_ab[idx] = ab;
    sim_encoder_edge(idx, ab);
}

/* A faulty sensor's line gets none of the world's echoes, except the end of a world pulse already
 * high when the fault began: the sensor ends the pulse in flight (a line left high would be a line
 * stuck high, which neither fault is). */
static void echo_deliver(uint8_t idx, uint8_t level, int injected)
{
    if (idx < HAL_SONAR_MAX && !injected) {
        uint16_t bit = (uint16_t)(1u << idx);
        bool in_flight = level == 0u && (S.world_echo_high & bit) != 0u;
        if (S.sonar_fault[idx] != SIL_FAULT_NONE && !in_flight) {
            return;
        }
        S.world_echo_high = (uint16_t)(level != 0u ? S.world_echo_high | bit : S.world_echo_high & ~bit);
    }
    sim_sonar_echo_edge(idx, level);
}

/* An interrupt takes CPU time: the loop cannot run meanwhile (sil_set_isr_cost_us). */
static void isr_cost(void)
{
    if (S.isr_cost_us != 0u) {
        S.now_us += S.isr_cost_us;
        sim_time_set_us((uint32_t)S.now_us);
    }
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
    sim_eeprom_set_write_us(SIL_EEPROM_WRITE_US);
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
        if (e.kind == SIL_EV_ENCODER) {
            encoder_deliver(e.idx, e.val);
        } else {
            echo_deliver(e.idx, e.val, e.kind == SIL_EV_ECHO_FAULT);
        }
        isr_cost();
    }
}

/* The native watchdog model: a kick gap beyond the timeout resets the core (sil_api.h). */
static void watch_kicks(void)
{
    uint32_t kicks = sim_watchdog_kicks();
    if (kicks != S.wdt_kicks_seen) {
        uint64_t gap = S.now_us - S.last_kick_us;
        if (S.wdt_kicks_seen != 0u && gap > S.kick_gap_max_us) {
            S.kick_gap_max_us = gap > 0xFFFFFFFFu ? 0xFFFFFFFFu : (uint32_t)gap;
        }
        S.wdt_kicks_seen = kicks;
        S.last_kick_us = S.now_us;
        return;
    }
    uint16_t timeout_ms = sim_watchdog_timeout_ms();
    if (timeout_ms != 0u && kicks != 0u && S.now_us - S.last_kick_us > (uint64_t)timeout_ms * 1000u) {
        sil_fault_reset(SIL_RESET_WATCHDOG);
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
        watch_kicks(); /* an ISR storm may have held the loop off past the timeout */
        agnav_loop_once();
        S.loop_passes++;
        watch_kicks();
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
void sil_encoder_edge(uint8_t idx, uint8_t ab) { encoder_deliver(idx, ab); }

uint32_t sil_queue_encoder_edges(uint8_t idx, const uint64_t *t_us, const uint8_t *ab, uint32_t n)
{
    return sil_ev_push_edges(s_heap, SIL_EVENT_MAX, &S.ev_n, &S.ev_seq, idx, t_us, ab, n);
}

int sil_queue_echo(uint8_t idx, uint64_t t_us, uint8_t level) { return ev_push(SIL_EV_ECHO, idx, level != 0u, t_us); }

uint32_t sil_take_triggers(uint8_t *idx, uint64_t *t_us, uint32_t max) { return sil_trig_take(&S.trig, idx, t_us, max); }

uint32_t sil_sonar_trigger_count(uint8_t idx) { return sim_sonar_trigger_count(idx); }
void sil_sonar_echo_edge(uint8_t idx, uint8_t level) { echo_deliver(idx, level, 0); }
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

/* Before the clock runs (a host writing parameters for the next boot): lib/storage's writer to the end,
 * each byte's programming time skipped. */
int sil_param_save(void)
{
    storage_request(STORAGE_PARAMS);
    while (storage_pending(STORAGE_PARAMS)) {
        sim_eeprom_settle();
        storage_tick();
    }
    uint8_t failed;
    (void)storage_take_done(&failed);
    return (failed & STORAGE_BIT(STORAGE_PARAMS)) != 0u ? -1 : 0;
}
uint32_t sil_eeprom_size(void) { return hal_eeprom_size(); }
void sil_eeprom_read(uint32_t addr, uint8_t *dst, uint32_t len) { hal_eeprom_read((uint16_t)addr, dst, (uint16_t)len); }
void sil_eeprom_write(uint32_t addr, const uint8_t *src, uint32_t len)
{
    for (uint32_t i = 0; i < len && addr + i < SIM_EEPROM_SIZE; i++) {
        sim_eeprom_bytes()[addr + i] = src[i];
    }
}
uint32_t sil_eeprom_idle_calls(void) { return sim_eeprom_idle_calls(); }
uint32_t sil_eeprom_writes(void) { return sim_eeprom_writes(); }

/* ---- fault injection (sil_api.h) ------------------------------------------------------------- */
int sil_fault_encoder(uint8_t idx, int mode)
{
    if (idx >= HAL_ENCODER_MAX || mode < SIL_FAULT_NONE || mode > SIL_ENC_NOISE) {
        return -1;
    }
    S.enc_fault[idx] = (uint8_t)mode;
    if (mode == SIL_ENC_DISCONNECTED && S.enc_ab[idx] != 3u) {
        S.enc_ab[idx] = 3u; /* pull-ups take both lines high */
        sim_encoder_edge(idx, 3u);
    }
    return 0;
}

int sil_fault_sonar(uint8_t idx, int mode)
{
    if (idx >= HAL_SONAR_MAX || mode < SIL_FAULT_NONE || mode > SIL_SONAR_ZERO) {
        return -1;
    }
    S.sonar_fault[idx] = (uint8_t)mode;
    return 0;
}

int sil_eeprom_record(int which, uint32_t *addr, uint32_t *len)
{
    return sil_eeprom_map(which, params_count(), addr, len);
}

void sil_eeprom_corrupt(uint32_t addr, uint32_t len, uint8_t xor_mask)
{
    uint8_t *e = sim_eeprom_bytes();
    for (uint32_t i = 0; i < len && addr + i < SIM_EEPROM_SIZE; i++) {
        e[addr + i] ^= xor_mask;
    }
}

void sil_fault_reset(int cause)
{
    static uint8_t keep[SIM_EEPROM_SIZE];
    memcpy(keep, sim_eeprom_bytes(), SIM_EEPROM_SIZE);
    sim_reset(); /* pins, UART buffers, timers: what a core reset clears */
    S.world_echo_high = 0u; /* sim_reset() let the echo lines go low */
    sim_eeprom_set_write_us(SIL_EEPROM_WRITE_US);
    memcpy(sim_eeprom_bytes(), keep, SIM_EEPROM_SIZE);
    sim_sonar_on_trigger(on_trigger);
    sim_set_reset_cause((hal_reset_cause_t)cause);
    S.resets++;
    S.wdt_kicks_seen = 0u;
    memset(S.enc_ab, 0, sizeof S.enc_ab);
    set_time(S.now_us);
    agnav_setup();
}

uint32_t sil_resets(void) { return S.resets; }

uint32_t sil_kick_gap_max_us(void)
{
    uint32_t g = S.kick_gap_max_us;
    S.kick_gap_max_us = 0u;
    return g;
}

uint32_t sil_isr_burst(uint8_t idx, uint32_t n, uint32_t period_us)
{
    static const uint8_t GRAY[4] = {0u, 2u, 3u, 1u}; /* A leads B: counts up */
    uint8_t phase = 0u;
    for (uint8_t k = 0; k < 4u; k++) {
        if (GRAY[k] == S.enc_ab[idx < HAL_ENCODER_MAX ? idx : 0u]) {
            phase = k;
        }
    }
    uint32_t k = 0u;
    for (; k < n; k++) {
        phase = (uint8_t)((phase + 1u) & 3u);
        if (!ev_push(SIL_EV_ENCODER, idx, GRAY[phase], S.now_us + (uint64_t)(k + 1u) * period_us)) {
            break;
        }
    }
    return k;
}

void sil_set_isr_cost_us(uint32_t us) { S.isr_cost_us = us; }
