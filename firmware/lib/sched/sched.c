/* Static task-table runner, see sched.h. */
#include "sched.h"

#include "hal.h"

static const sched_task_t *s_tasks;
static sched_stats_t *s_stats;
static uint8_t s_n;

void sched_init(const sched_task_t *tasks, uint8_t n, sched_stats_t *stats)
{
    s_tasks = tasks;
    s_stats = stats;
    s_n = (tasks != 0 && stats != 0) ? (n > SCHED_MAX_TASKS ? (uint8_t)SCHED_MAX_TASKS : n) : 0u;
    uint32_t now = hal_time_us();
    for (uint8_t i = 0; i < s_n; i++) {
        sched_stats_t *st = &s_stats[i];
        st->next_due_us = now;
        st->last_start_us = now;
        st->worst_us = 0u;
        st->runs = 0u;
        st->overruns = 0u;
        st->slips = 0u;
    }
}

uint8_t sched_run(uint32_t now_us)
{
    uint8_t ran = 0u;
    for (uint8_t i = 0; i < s_n; i++) {
        const sched_task_t *t = &s_tasks[i];
        sched_stats_t *st = &s_stats[i];
        int32_t late_us = (int32_t)(now_us - st->next_due_us);
        if (late_us < 0 || t->fn == 0) {
            continue;
        }
        uint32_t period_us = (uint32_t)t->period_ms * 1000UL;
        if (period_us == 0u) {
            period_us = 1000u;
        }
        if ((uint32_t)late_us > period_us) {
            /* More than a whole period late: count it, drop the missed runs. */
            if (st->slips < 0xFFFFu) {
                st->slips++;
            }
            st->next_due_us = now_us + period_us;
        } else {
            st->next_due_us += period_us;
        }
        uint32_t t0 = hal_time_us();
        st->last_start_us = t0;
        t->fn();
        uint32_t dt = hal_time_us() - t0;
        if (dt > st->worst_us) {
            st->worst_us = dt;
        }
        if (dt > t->budget_us && st->overruns < 0xFFFFu) {
            st->overruns++;
        }
        st->runs++;
        ran++;
    }
    return ran;
}

uint32_t sched_idle_us(uint32_t now_us)
{
    uint32_t best = 0xFFFFFFFFUL;
    for (uint8_t i = 0; i < s_n; i++) {
        int32_t d = (int32_t)(s_stats[i].next_due_us - now_us);
        if (d <= 0) {
            return 0u;
        }
        if ((uint32_t)d < best) {
            best = (uint32_t)d;
        }
    }
    return s_n == 0u ? 0u : best;
}

uint8_t sched_task_count(void) { return s_n; }

const sched_task_t *sched_task(uint8_t i) { return &s_tasks[i]; }

const sched_stats_t *sched_task_stats(uint8_t i) { return &s_stats[i]; }
