/*
 * Static task-table runner (cooperative, run from the main loop).
 *
 * main.c owns a const table of rows {fn, period_ms, budget_us, name}; every
 * loop pass calls sched_run(hal_time_us()). A task is due once per period;
 * due tasks run in table order (earlier rows first). Per task the runner
 * keeps, in a caller-provided stats array:
 *   - worst_us:  longest run, measured with hal_time_us() around the call
 *   - runs:      completed runs
 *   - overruns:  runs longer than budget_us
 *   - slips:     starts later than one full period after the due time; the
 *                missed periods are dropped (next due = start + period)
 * Otherwise the next due time advances by exactly one period, so the rate
 * does not drift with loop jitter. All time compares are wrap-safe.
 */
#ifndef AGNAV_SCHED_H
#define AGNAV_SCHED_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SCHED_MAX_TASKS 16u

typedef struct {
    void (*fn)(void);   /* task body; must return (cooperative) */
    uint16_t period_ms; /* 1..65535 */
    uint16_t budget_us; /* expected worst run time; longer counts as an overrun */
    const char *name;   /* for status reports */
} sched_task_t;

typedef struct {
    uint32_t next_due_us; /* hal time the task is next due */
    uint32_t last_start_us;
    uint32_t worst_us;
    uint32_t runs;
    uint16_t overruns;    /* saturating */
    uint16_t slips;       /* saturating */
} sched_stats_t;

/* Take the table (kept by pointer, n <= SCHED_MAX_TASKS, extra rows ignored)
 * and the stats array (n entries, zeroed here). Every task is first due at
 * hal_time_us() as read here. */
void sched_init(const sched_task_t *tasks, uint8_t n, sched_stats_t *stats);

/* Run every task that is due at now_us (hal time, us). Returns how many ran. */
uint8_t sched_run(uint32_t now_us);

/* Microseconds until the earliest next due time (0 if something is due). */
uint32_t sched_idle_us(uint32_t now_us);

/* The rows sched_init() kept (0 before it), row i of the table and its stats (i < that count),
 * for status reports. */
uint8_t sched_task_count(void);
const sched_task_t *sched_task(uint8_t i);
const sched_stats_t *sched_task_stats(uint8_t i);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_SCHED_H */
