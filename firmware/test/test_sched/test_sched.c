/* Unity tests for lib/sched, on the simulated HAL clock. Task bodies
 * record when they ran; "slow" bodies advance the simulated clock to stand
 * for their run time. */
#include "unity.h"

#include "hal.h"
#include "sched.h"
#include "sim/hal_sim.h"

static uint32_t fast_runs, mid_runs, slow_runs;
static uint32_t fast_last_us, fast_min_gap_us, fast_max_gap_us;
static uint8_t order[8];
static uint8_t order_n;
static uint32_t heavy_cost_us;

static void task_fast(void)
{
    uint32_t now = hal_time_us();
    if (fast_runs > 0u) {
        uint32_t gap = now - fast_last_us;
        if (gap < fast_min_gap_us) {
            fast_min_gap_us = gap;
        }
        if (gap > fast_max_gap_us) {
            fast_max_gap_us = gap;
        }
    }
    fast_last_us = now;
    fast_runs++;
    if (order_n < sizeof order) {
        order[order_n++] = 0u;
    }
}

static void task_mid(void)
{
    mid_runs++;
    if (order_n < sizeof order) {
        order[order_n++] = 1u;
    }
}

static void task_slow(void)
{
    slow_runs++;
    if (order_n < sizeof order) {
        order[order_n++] = 2u;
    }
}

static void task_heavy(void) { sim_time_advance_us(heavy_cost_us); }
static void task_light(void) { sim_time_advance_us(500u); }

static const sched_task_t RATES[] = {
    {task_fast, 20u, 2000u, "ctl50"},
    {task_mid, 100u, 2000u, "sonar10"},
    {task_slow, 1000u, 2000u, "status1"},
};

static const sched_task_t LOAD[] = {
    {task_heavy, 20u, 1000u, "heavy"},
    {task_light, 20u, 1000u, "light"},
};

static sched_stats_t stats[3];

/* Main loop: call sched_run every 700 or 1300 us (jitter) for dur_us. */
static void loop_for(uint32_t dur_us)
{
    uint32_t t_end = hal_time_us() + dur_us;
    uint8_t k = 0;
    while ((int32_t)(t_end - hal_time_us()) > 0) {
        sched_run(hal_time_us());
        sim_time_advance_us((k++ & 1u) != 0u ? 1300u : 700u);
    }
}

void setUp(void)
{
    sim_reset();
    fast_runs = mid_runs = slow_runs = 0u;
    fast_last_us = 0u;
    fast_min_gap_us = 0xFFFFFFFFUL;
    fast_max_gap_us = 0u;
    order_n = 0u;
    heavy_cost_us = 3000u;
    sched_init(RATES, 3u, stats);
}

void tearDown(void) {}

void test_sched_run_respects_rates_over_5_simulated_seconds(void)
{
    loop_for(5000000UL);
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(1u, 250u, fast_runs, "50 Hz task");
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(1u, 50u, mid_runs, "10 Hz task");
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(1u, 5u, slow_runs, "1 Hz task");
    TEST_ASSERT_EQUAL_UINT32(fast_runs, stats[0].runs);
    /* jitter of one loop pass at most, no drift */
    TEST_ASSERT_TRUE_MESSAGE(fast_min_gap_us >= 20000UL - 1300UL, "50 Hz task ran early");
    TEST_ASSERT_TRUE_MESSAGE(fast_max_gap_us <= 20000UL + 1300UL, "50 Hz task ran late");
    TEST_ASSERT_EQUAL_UINT16(0u, stats[0].slips);
    TEST_ASSERT_EQUAL_UINT16(0u, stats[0].overruns);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0u, stats[0].worst_us, "instant task measured as zero");
}

void test_sched_run_counts_overrun_when_task_exceeds_budget(void)
{
    static sched_stats_t ls[2];
    sched_init(LOAD, 2u, ls);
    loop_for(1000000UL);
    TEST_ASSERT_UINT32_WITHIN(1u, 50u, ls[0].runs);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(3000u, ls[0].worst_us, "worst time of the heavy task");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE((uint16_t)ls[0].runs, ls[0].overruns, "every heavy run overran");
    TEST_ASSERT_EQUAL_UINT32(500u, ls[1].worst_us);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, ls[1].overruns, "light task within budget");
    /* a single slower run is caught as well */
    heavy_cost_us = 200u;
    sched_init(LOAD, 2u, ls);
    loop_for(200000UL);
    TEST_ASSERT_EQUAL_UINT16(0u, ls[0].overruns);
    heavy_cost_us = 1001u;
    uint32_t runs = ls[0].runs;
    while (ls[0].runs == runs) { /* exactly one more heavy run */
        sched_run(hal_time_us());
        sim_time_advance_us(700u);
    }
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(1u, ls[0].overruns, "1001 us > 1000 us budget");
    TEST_ASSERT_EQUAL_UINT32(1001u, ls[0].worst_us);
}

void test_sched_run_counts_slip_and_drops_missed_periods_after_stall(void)
{
    loop_for(100000UL);
    uint32_t before = stats[0].runs;
    sim_time_advance_us(95000UL); /* loop stalled ~4.75 periods */
    uint32_t now = hal_time_us();
    sched_run(now);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(before + 1u, stats[0].runs, "no burst of catch-up runs");
    TEST_ASSERT_EQUAL_UINT16(1u, stats[0].slips);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(now + 20000UL, stats[0].next_due_us, "resynced to the late start");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, stats[2].slips, "1 Hz task was not a period late");
    sched_run(now + 1000u);
    TEST_ASSERT_EQUAL_UINT32(before + 1u, stats[0].runs);
}

void test_sched_run_keeps_rates_across_timer_wrap(void)
{
    sim_time_set_us(0xFFFFFFFFUL - 2500000UL);
    sched_init(RATES, 3u, stats);
    loop_for(5000000UL);
    TEST_ASSERT_TRUE_MESSAGE(hal_time_us() < 3000000UL, "clock wrapped");
    TEST_ASSERT_UINT32_WITHIN(1u, 250u, fast_runs);
    TEST_ASSERT_UINT32_WITHIN(1u, 50u, mid_runs);
    TEST_ASSERT_UINT32_WITHIN(1u, 5u, slow_runs);
    TEST_ASSERT_EQUAL_UINT16(0u, stats[0].slips);
    TEST_ASSERT_TRUE(fast_max_gap_us <= 20000UL + 1300UL);
}

void test_sched_run_runs_due_tasks_in_table_order(void)
{
    TEST_ASSERT_EQUAL_UINT8(3u, sched_run(hal_time_us()));
    TEST_ASSERT_EQUAL_UINT8(3u, order_n);
    TEST_ASSERT_EQUAL_UINT8(0u, order[0]);
    TEST_ASSERT_EQUAL_UINT8(1u, order[1]);
    TEST_ASSERT_EQUAL_UINT8(2u, order[2]);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(0u, sched_run(hal_time_us()), "nothing due twice");
}

void test_sched_idle_us_reports_time_to_next_due(void)
{
    TEST_ASSERT_EQUAL_UINT32(0u, sched_idle_us(hal_time_us()));
    sched_run(hal_time_us());
    TEST_ASSERT_EQUAL_UINT32(20000u, sched_idle_us(hal_time_us()));
    sim_time_advance_us(5000u);
    TEST_ASSERT_EQUAL_UINT32(15000u, sched_idle_us(hal_time_us()));
}

/* What telemetry's "T_<task>" round robin reads: the rows sched_init() kept and each one's stats. */
void test_sched_reports_the_rows_it_runs_and_their_stats(void)
{
    static sched_stats_t ls[2];
    sched_init(LOAD, 2u, ls);
    TEST_ASSERT_EQUAL_UINT8(2u, sched_task_count());
    TEST_ASSERT_EQUAL_PTR(&LOAD[1], sched_task(1u));
    TEST_ASSERT_EQUAL_STRING("heavy", sched_task(0u)->name);
    loop_for(100000UL);
    TEST_ASSERT_EQUAL_PTR(&ls[0], sched_task_stats(0u));
    TEST_ASSERT_EQUAL_UINT32(3000u, sched_task_stats(0u)->worst_us);
    TEST_ASSERT_EQUAL_UINT32(500u, sched_task_stats(1u)->worst_us);
    sched_init(0, 3u, stats); /* no table: nothing to run or report */
    TEST_ASSERT_EQUAL_UINT8(0u, sched_task_count());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_sched_run_respects_rates_over_5_simulated_seconds);
    RUN_TEST(test_sched_run_counts_overrun_when_task_exceeds_budget);
    RUN_TEST(test_sched_run_counts_slip_and_drops_missed_periods_after_stall);
    RUN_TEST(test_sched_run_keeps_rates_across_timer_wrap);
    RUN_TEST(test_sched_run_runs_due_tasks_in_table_order);
    RUN_TEST(test_sched_idle_us_reports_time_to_next_due);
    RUN_TEST(test_sched_reports_the_rows_it_runs_and_their_stats);
    return UNITY_END();
}
