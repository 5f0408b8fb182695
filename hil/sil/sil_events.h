/*
 * The SIL's timed event queue (encoder edges, echo edges), shared by the native SIL
 * (hil/sil/sil_api.c) and the simavr one (hil/simavr/avr_sil.c): a binary min-heap on
 * (t_us, seq), so events at the same microsecond keep their queueing order. Also the queue
 * of sonar triggers the firmware fired, which both backends hand to the host the same way.
 */
#ifndef AGNAV_SIL_EVENTS_H
#define AGNAV_SIL_EVENTS_H

#include <stdint.h>

#include "sil_api.h" /* SIL_TRIGGER_MAX */

/* What an event is: an encoder's A/B levels, an echo line's level, or an echo the SIL made up for
 * a sonar told to read zero (SIL_SONAR_ZERO). */
enum { SIL_EV_ENCODER = 0, SIL_EV_ECHO = 1, SIL_EV_ECHO_FAULT = 2 };

typedef struct {
    uint64_t t_us;
    uint64_t seq; /* queueing order: ties keep it */
    uint8_t kind;
    uint8_t idx;
    uint8_t val;
} sil_event_t;

static inline int sil_ev_less(const sil_event_t *a, const sil_event_t *b)
{
    return a->t_us < b->t_us || (a->t_us == b->t_us && a->seq < b->seq);
}

/* Push; returns 0 when the heap (capacity cap) is full. */
static inline int sil_ev_push(sil_event_t *heap, uint32_t cap, uint32_t *n, uint64_t *seq, uint8_t kind, uint8_t idx,
                              uint8_t val, uint64_t t_us)
{
    if (*n >= cap) {
        return 0;
    }
    sil_event_t e = {t_us, (*seq)++, kind, idx, val};
    uint32_t i = (*n)++;
    while (i > 0u) {
        uint32_t p = (i - 1u) / 2u;
        if (!sil_ev_less(&e, &heap[p])) {
            break;
        }
        heap[i] = heap[p];
        i = p;
    }
    heap[i] = e;
    return 1;
}

/* Push count encoder edges of encoder idx (levels ab[k] at t_us[k]) in order; stops at the first
 * that does not fit and returns how many went in (both backends' sil_queue_encoder_edges). */
static inline uint32_t sil_ev_push_edges(sil_event_t *heap, uint32_t cap, uint32_t *n, uint64_t *seq, uint8_t idx,
                                         const uint64_t *t_us, const uint8_t *ab, uint32_t count)
{
    uint32_t k = 0u;
    while (k < count && sil_ev_push(heap, cap, n, seq, SIL_EV_ENCODER, idx, ab[k], t_us[k])) {
        k++;
    }
    return k;
}

/* Pop the earliest event; *n must be > 0. */
static inline sil_event_t sil_ev_pop(sil_event_t *heap, uint32_t *n)
{
    sil_event_t top = heap[0];
    sil_event_t last = heap[--(*n)];
    if (*n == 0u) {
        return top;
    }
    uint32_t i = 0u;
    for (;;) {
        uint32_t c = 2u * i + 1u;
        if (c >= *n) {
            break;
        }
        if (c + 1u < *n && sil_ev_less(&heap[c + 1u], &heap[c])) {
            c++;
        }
        if (!sil_ev_less(&heap[c], &last)) {
            break;
        }
        heap[i] = heap[c];
        i = c;
    }
    heap[i] = last;
    return top;
}

/* Sonar triggers fired and not yet taken by the host (sil_take_triggers), oldest first. */
typedef struct {
    uint32_t head, n;
    uint8_t idx[SIL_TRIGGER_MAX];
    uint64_t t_us[SIL_TRIGGER_MAX];
} sil_trigger_queue_t;

/* Record a trigger of sonar idx at t_us; returns 0 (and keeps the older ones) when the queue is full. */
static inline int sil_trig_push(sil_trigger_queue_t *q, uint8_t idx, uint64_t t_us)
{
    if (q->n >= SIL_TRIGGER_MAX) {
        return 0;
    }
    uint32_t k = (q->head + q->n) % SIL_TRIGGER_MAX;
    q->idx[k] = idx;
    q->t_us[k] = t_us;
    q->n++;
    return 1;
}

/* Take up to max triggers, oldest first; returns how many. */
static inline uint32_t sil_trig_take(sil_trigger_queue_t *q, uint8_t *idx, uint64_t *t_us, uint32_t max)
{
    uint32_t k = 0u;
    while (k < max && q->n > 0u) {
        idx[k] = q->idx[q->head];
        t_us[k] = q->t_us[q->head];
        q->head = (q->head + 1u) % SIL_TRIGGER_MAX;
        q->n--;
        k++;
    }
    return k;
}

#endif
