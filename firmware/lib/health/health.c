#include "health.h"

#include <string.h>

static struct {
    health_params_t p;
    uint8_t enc_n;
    bool started;
    uint32_t last_ms;
    uint16_t count[HEALTH_ENC_MAX];
    uint16_t edges[HEALTH_ENC_MAX];
    uint16_t silent_ms[HEALTH_ENC_MAX];
    uint8_t fault_run[SONAR_RING_MAX];
    uint8_t zero_run[SONAR_RING_MAX];
    uint32_t bits;
    uint32_t reported;
} h;

void health_init(const health_params_t *params, uint8_t enc_count)
{
    memset(&h, 0, sizeof h);
    h.p = *params;
    h.enc_n = enc_count > HEALTH_ENC_MAX ? HEALTH_ENC_MAX : enc_count;
}

void health_set_params(const health_params_t *params) { h.p = *params; }

void health_encoders(uint32_t now_ms, bool driving, const uint16_t *count_lo, const uint16_t *edges_lo,
                     uint8_t ratio_faults)
{
    uint16_t dt_ms = (uint16_t)((uint32_t)(now_ms - h.last_ms) > 0xFFFFu ? 0xFFFFu : now_ms - h.last_ms);
    if (!h.started) {
        dt_ms = 0u;
        h.started = true;
        memcpy(h.edges, edges_lo, h.enc_n * sizeof edges_lo[0]);
    }
    h.last_ms = now_ms;
    for (uint8_t i = 0; i < h.enc_n; i++) {
        if (!driving || count_lo[i] != h.count[i]) {
            h.silent_ms[i] = 0u;
        } else {
            uint32_t s = (uint32_t)h.silent_ms[i] + dt_ms;
            h.silent_ms[i] = s > 0xFFFFu ? 0xFFFFu : (uint16_t)s;
        }
        h.count[i] = count_lo[i];
        if (h.p.enc_stuck_ms != 0u && h.silent_ms[i] >= h.p.enc_stuck_ms) {
            h.bits |= 1UL << (HEALTH_ENC_STUCK_SHIFT + i);
        }
        uint16_t edges = (uint16_t)(edges_lo[i] - h.edges[i]);
        h.edges[i] = edges_lo[i];
        if ((h.p.enc_edges_max != 0u && edges > h.p.enc_edges_max) || (ratio_faults & (1u << i)) != 0u) {
            h.bits |= 1UL << (HEALTH_ENC_ERROR_SHIFT + i);
        }
    }
}

void health_sonar(const sonar_frame_t *f)
{
    uint8_t n = f->count < SONAR_RING_MAX ? f->count : SONAR_RING_MAX;
    for (uint8_t i = 0; i < n; i++) {
        bool fault = f->status[i] == SONAR_FAULT;
        bool zero = f->status[i] == SONAR_VALID && f->ranges_mm[i] < HEALTH_SONAR_ZERO_MM;
        h.fault_run[i] = fault ? (uint8_t)(h.fault_run[i] < 255u ? h.fault_run[i] + 1u : 255u) : 0u;
        h.zero_run[i] = zero ? (uint8_t)(h.zero_run[i] < 255u ? h.zero_run[i] + 1u : 255u) : 0u;
        if (h.p.sonar_fault_frames != 0u && h.fault_run[i] >= h.p.sonar_fault_frames) {
            h.bits |= 1UL << (HEALTH_SONAR_TIMEOUT_SHIFT + i);
        }
        if (h.p.sonar_zero_frames != 0u && h.zero_run[i] >= h.p.sonar_zero_frames) {
            h.bits |= 1UL << (HEALTH_SONAR_ZERO_SHIFT + i);
        }
    }
}

uint32_t health_bits(void) { return h.bits; }
bool health_encoder_fault(void) { return (h.bits & HEALTH_ENC_MASK) != 0u; }
bool health_sonar_fault(void) { return (h.bits & HEALTH_SONAR_MASK) != 0u; }

uint32_t health_take_new(void)
{
    uint32_t fresh = h.bits & ~h.reported;
    fresh &= ~fresh + 1u; /* lowest set bit */
    h.reported |= fresh;
    return fresh;
}

void health_clear(void)
{
    h.bits = 0u;
    h.reported = 0u;
    memset(h.silent_ms, 0, sizeof h.silent_ms);
    memset(h.fault_run, 0, sizeof h.fault_run);
    memset(h.zero_run, 0, sizeof h.zero_run);
}
