/* Unity tests for lib/sonar_ring, driven by the simulated HAL: a small echo
 * model answers each trigger (through sim_sonar_on_trigger) with a rising
 * edge 450 us later and a falling edge after the round-trip time. */
#include "unity.h"

#include "hal.h"
#include "sim/hal_sim.h"
#include "sonar_ring.h"

#define MODE_ECHO 0u   /* target at world_mm */
#define MODE_FREE 1u   /* nothing in range: HC-SR04 holds echo high ~38 ms */
#define MODE_DEAD 2u   /* no rising edge at all (unplugged sensor) */
#define MODE_STUCK 3u  /* echo rises once and never falls */
#define MODE_HELD 4u   /* 450 us after the first trigger the line goes high and is held there
                          (sim_sonar_echo_hold_high): an output stuck high, an unplugged sensor on
                          a pulled-up pin */
#define MODE_SHORT 5u  /* 60 us pulse 300 us after every trigger: reads ~10 mm (a shorted or ringing
                          transducer, or a target touching the sensor) */

#define EV_RISE 1u
#define EV_FALL 2u

static uint16_t world_mm[SONAR_RING_MAX];
static uint8_t mode[SONAR_RING_MAX];
static uint32_t rise_at[SONAR_RING_MAX];
static uint32_t fall_at[SONAR_RING_MAX];
static uint8_t due[SONAR_RING_MAX];

/* cross-talk bookkeeping (filled by the trigger hook) */
static uint8_t ring_n;
static uint32_t last_trig_us[SONAR_RING_MAX];
static uint16_t trig_seen;
static uint32_t min_neighbour_gap_us;
static uint16_t neighbour_violations;

static void on_trigger(uint8_t idx, uint32_t t_us)
{
    if (ring_n >= 2u) {
        uint8_t nb[2];
        nb[0] = (uint8_t)((idx + 1u) % ring_n);
        nb[1] = (uint8_t)((idx + ring_n - 1u) % ring_n);
        for (uint8_t k = 0; k < 2u; k++) {
            if ((trig_seen & (1u << nb[k])) != 0u) {
                uint32_t gap = t_us - last_trig_us[nb[k]];
                if (gap < min_neighbour_gap_us) {
                    min_neighbour_gap_us = gap;
                }
                if (gap < SONAR_NEIGHBOUR_GAP_US) {
                    neighbour_violations++;
                }
            }
        }
    }
    last_trig_us[idx] = t_us;
    trig_seen = (uint16_t)(trig_seen | (1u << idx));

    switch (mode[idx]) {
    case MODE_ECHO:
        rise_at[idx] = t_us + 450u;
        fall_at[idx] = rise_at[idx] + sonar_ring_echo_us_from_mm(world_mm[idx]);
        due[idx] = EV_RISE | EV_FALL;
        break;
    case MODE_SHORT:
        rise_at[idx] = t_us + 300u;
        fall_at[idx] = rise_at[idx] + 60u;
        due[idx] = EV_RISE | EV_FALL;
        break;
    case MODE_FREE:
        rise_at[idx] = t_us + 450u;
        fall_at[idx] = rise_at[idx] + 38000u;
        due[idx] = EV_RISE | EV_FALL;
        break;
    case MODE_STUCK:
    case MODE_HELD:
        if (due[idx] == 0u && rise_at[idx] == 0u) { /* only the first trigger */
            rise_at[idx] = t_us + 450u;
            due[idx] = EV_RISE;
        }
        break;
    default:
        due[idx] = 0u;
        break;
    }
}

/* Earliest pending echo edge; returns its sensor or 0xFF. */
static uint8_t next_event(uint32_t *t_out, uint8_t *level_out)
{
    uint8_t best = 0xFFu;
    uint32_t now = hal_time_us();
    int32_t best_dt = 0;
    for (uint8_t i = 0; i < SONAR_RING_MAX; i++) {
        if ((due[i] & EV_RISE) != 0u) {
            int32_t dt = (int32_t)(rise_at[i] - now);
            if (best == 0xFFu || dt < best_dt) {
                best = i;
                best_dt = dt;
                *t_out = rise_at[i];
                *level_out = 1u;
            }
        } else if ((due[i] & EV_FALL) != 0u) {
            int32_t dt = (int32_t)(fall_at[i] - now);
            if (best == 0xFFu || dt < best_dt) {
                best = i;
                best_dt = dt;
                *t_out = fall_at[i];
                *level_out = 0u;
            }
        }
    }
    return best;
}

/* Run the main loop for dur_us, calling sonar_ring_step every loop_us and
 * injecting echo edges at their exact times. */
static void run_for(uint32_t dur_us, uint32_t loop_us)
{
    uint32_t t_end = hal_time_us() + dur_us;
    while ((int32_t)(t_end - hal_time_us()) > 0) {
        uint32_t next = hal_time_us() + loop_us;
        for (;;) {
            uint32_t t_ev = 0;
            uint8_t level = 0;
            uint8_t idx = next_event(&t_ev, &level);
            if (idx == 0xFFu || (int32_t)(t_ev - next) > 0) {
                break;
            }
            if ((int32_t)(t_ev - hal_time_us()) > 0) {
                sim_time_set_us(t_ev);
            }
            due[idx] = (uint8_t)(due[idx] & (level != 0u ? (uint8_t)~EV_RISE : (uint8_t)~EV_FALL));
            if (mode[idx] == MODE_HELD) {
                sim_sonar_echo_hold_high(idx, true);
            } else {
                sim_sonar_echo_edge(idx, level);
            }
        }
        sim_time_set_us(next);
        sonar_ring_step(hal_time_us());
    }
}

static void ring_setup(const sonar_ring_cfg_t *cfg)
{
    ring_n = cfg->count;
    TEST_ASSERT_TRUE_MESSAGE(sonar_ring_init(cfg), "init accepts preset");
}

void setUp(void)
{
    sim_reset();
    for (uint8_t i = 0; i < SONAR_RING_MAX; i++) {
        world_mm[i] = 2000u;
        mode[i] = MODE_ECHO;
        rise_at[i] = 0u;
        fall_at[i] = 0u;
        due[i] = 0u;
        last_trig_us[i] = 0u;
    }
    trig_seen = 0u;
    min_neighbour_gap_us = 0xFFFFFFFFUL;
    neighbour_violations = 0u;
    sim_sonar_on_trigger(on_trigger);
    ring_setup(&SONAR_RING_12_SDLG);
}

void tearDown(void) { sim_sonar_on_trigger(0); }

/* ---- conversion ------------------------------------------------------ */

void test_sonar_ring_mm_from_echo_us_uses_343_m_s_round_trip(void)
{
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, sonar_ring_mm_from_echo_us(0u), "zero width");
    /* 100 mm: 2 * 0.1 m / 343 m/s = 583.1 us */
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(1u, 100u, sonar_ring_mm_from_echo_us(583u), "10 cm");
    /* 3 m: 17492.7 us */
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(1u, 3000u, sonar_ring_mm_from_echo_us(17493u), "3 m");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(65535u, sonar_ring_mm_from_echo_us(4000000UL), "saturates");
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(1u, 5831u, sonar_ring_echo_us_from_mm(1000u), "inverse at 1 m");
}

/* ---- measurement chain ---------------------------------------------- */

void test_sonar_ring_step_measures_near_target_at_100mm_within_5mm(void)
{
    world_mm[0] = 100u;
    run_for(400000UL, 250u);
    sonar_frame_t f;
    TEST_ASSERT_TRUE_MESSAGE(sonar_ring_snapshot(&f), "a ring completed");
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_VALID, f.status[0], "S0 valid");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(5u, 100u, f.ranges_mm[0], "S0 at 10 cm");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(5u, 2000u, f.ranges_mm[6], "S6 at 2 m");
}

void test_sonar_ring_step_measures_far_target_at_3m_within_10mm(void)
{
    world_mm[5] = 3000u;
    run_for(400000UL, 1000u); /* coarse 1 ms loop: timing still comes from the ISR stamps */
    sonar_frame_t f;
    sonar_ring_snapshot(&f);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_VALID, f.status[5], "S5 valid");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(10u, 3000u, f.ranges_mm[5], "S5 at 3 m");
}

void test_sonar_ring_step_reports_no_echo_when_pulse_runs_past_max_range(void)
{
    mode[3] = MODE_FREE;     /* echo held high 38 ms: never falls inside the slot */
    world_mm[4] = 4500u;     /* falls, but later than the 4 m timeout */
    run_for(400000UL, 250u);
    sonar_frame_t f;
    sonar_ring_snapshot(&f);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_NO_ECHO, f.status[3], "free space, pulse still high");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(4000u, f.ranges_mm[3], "free space reads max range");
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_NO_ECHO, f.status[4], "pulse longer than max range");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, sonar_ring_fault_count(3), "free space is not a fault");
}

/* An echo that starts right after the trigger and ends at once is a reading of ~10 mm, VALID: the
 * health monitor's zero-run rule ("reads zero") diagnoses it, not the ring's FAULT ("never echoes"). */
void test_sonar_ring_step_reads_short_echo_right_after_trigger_as_valid_10mm(void)
{
    mode[0] = MODE_SHORT;  /* group 0: first of the pass */
    mode[11] = MODE_SHORT; /* group 2: last of the pass */
    run_for(400000UL, 250u);
    sonar_frame_t f;
    TEST_ASSERT_TRUE_MESSAGE(sonar_ring_snapshot(&f), "a ring completed");
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_VALID, f.status[0], "short echo: VALID");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(1u, 10u, f.ranges_mm[0], "60 us: 10 mm");
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_VALID, f.status[11], "short echo in the last group: VALID");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(1u, 10u, f.ranges_mm[11], "last group: 10 mm");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, sonar_ring_fault_count(0), "no fault counted");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, sonar_ring_fault_count(11), "no fault counted, last group");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(5u, 2000u, f.ranges_mm[1], "neighbour unaffected");
}

void test_sonar_ring_step_reports_fault_and_counts_when_no_rising_edge(void)
{
    mode[7] = MODE_DEAD;
    run_for(500000UL, 250u);
    sonar_frame_t f;
    sonar_ring_snapshot(&f);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_FAULT, f.status[7], "no rise -> FAULT");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, f.ranges_mm[7], "fault range 0");
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(1u, 5u, sonar_ring_fault_count(7), "one fault per 96 ms pass in 0.5 s");
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_VALID, f.status[6], "neighbour unaffected");
}

void test_sonar_ring_step_reports_fault_when_echo_line_stuck_high(void)
{
    mode[2] = MODE_STUCK;
    run_for(400000UL, 250u);
    sonar_frame_t f;
    sonar_ring_snapshot(&f);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_FAULT, f.status[2], "line high at trigger -> FAULT");
    TEST_ASSERT_TRUE_MESSAGE(sonar_ring_fault_count(2) >= 2u, "faults counted each pass");
}

/* Runs the ring for dur_us (250 us loop) and checks every frame it publishes: sensor `held` is
 * FAULT with range 0 in each (never an echo or a range), the others VALID. Returns the frames. */
static uint32_t frames_with_sensor_faulted(uint8_t held, uint32_t dur_us, uint32_t *first_seq)
{
    uint32_t frames = 0u;
    sonar_frame_t f;
    for (uint32_t t = 0; t < dur_us; t += 1000u) {
        run_for(1000u, 250u);
        if (!sonar_ring_snapshot(&f)) {
            continue;
        }
        if (frames == 0u) {
            *first_seq = f.seq;
        }
        frames++;
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_FAULT, f.status[held], "held-high line: FAULT in every frame");
        TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, f.ranges_mm[held], "held-high line: no range");
        for (uint8_t i = 0; i < f.count; i++) {
            if (i != held && mode[i] == MODE_ECHO) {
                TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_VALID, f.status[i], "other sensors unaffected");
            }
        }
    }
    return frames;
}

/* One fault per published frame, plus at most the one of the pass under way. */
static void check_one_fault_per_pass(uint8_t idx, uint32_t frames)
{
    uint32_t faults = sonar_ring_fault_count(idx);
    TEST_ASSERT_TRUE_MESSAGE(faults >= frames, "a frame's FAULT not counted");
    TEST_ASSERT_TRUE_MESSAGE(faults <= frames + 1u, "more than one fault per pass");
}

/* The line rises where an echo would start and never falls again: no pass may read it as free
 * space. One sensor of each firing group (6: group 0, 10: group 1, 2: group 2 = the last group
 * of a pass). */
void test_sonar_ring_step_reports_fault_in_every_frame_when_echo_line_goes_high_and_stays(void)
{
    static const uint8_t held[3] = {6u, 10u, 2u};
    for (uint8_t k = 0; k < 3u; k++) {
        setUp();
        mode[held[k]] = MODE_HELD;
        uint32_t first_seq = 0u;
        uint32_t frames = frames_with_sensor_faulted(held[k], 600000UL, &first_seq);
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(1u, first_seq, "every frame seen from the first");
        TEST_ASSERT_TRUE_MESSAGE(frames >= 6u, "frames kept coming at ~10 Hz");
        check_one_fault_per_pass(held[k], frames);
    }
}

/* Power-on with the line already high (an unplugged sonar on D20/D21, the Mega's I2C pull-ups):
 * no edge ever reaches the ring. */
void test_sonar_ring_step_reports_fault_when_echo_line_high_from_power_on(void)
{
    sim_reset();
    sim_sonar_on_trigger(on_trigger);
    sim_sonar_echo_hold_high(9u, true); /* before the ring attaches: no edge */
    mode[9] = MODE_DEAD;
    ring_setup(&SONAR_RING_12_SDLG);
    uint32_t first_seq = 0u;
    uint32_t frames = frames_with_sensor_faulted(9u, 600000UL, &first_seq);
    TEST_ASSERT_EQUAL_UINT32(1u, first_seq);
    TEST_ASSERT_TRUE(frames >= 6u);
    check_one_fault_per_pass(9u, frames);
}

/* A free-space echo of the last group still high when its slot ends (HC-SR04: 38 ms): the frame
 * waits for it to end, while the next pass's first group fires on time, and holds that pass's
 * readings back: sensor 0 (group 0) dies from its 3rd trigger on, so frames 1 and 2 show it VALID
 * and frame 3 FAULT. */
static uint32_t s0_triggers;
static void on_trigger_s0_dies_from_third(uint8_t idx, uint32_t t_us)
{
    if (idx == 0u && ++s0_triggers >= 3u) {
        mode[0] = MODE_DEAD;
    }
    on_trigger(idx, t_us);
}

void test_sonar_ring_frame_holds_one_pass_while_last_group_free_space_echo_ends(void)
{
    s0_triggers = 0u;
    sim_sonar_on_trigger(on_trigger_s0_dies_from_third);
    mode[5] = MODE_FREE; /* group 2 */
    sonar_frame_t f;
    uint32_t last_stamp = 0u;
    for (uint32_t seq = 1u; seq <= 4u;) {
        run_for(250u, 250u);
        if (!sonar_ring_snapshot(&f)) {
            continue;
        }
        TEST_ASSERT_EQUAL_UINT32_MESSAGE(seq, f.seq, "a frame per pass");
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_NO_ECHO, f.status[5], "free space");
        TEST_ASSERT_EQUAL_UINT16(4000u, f.ranges_mm[5]);
        TEST_ASSERT_EQUAL_UINT8_MESSAGE(seq < 3u ? SONAR_VALID : SONAR_FAULT, f.status[0],
                                        "group 0 reading of this pass, not of the next");
        if (seq > 1u) {
            TEST_ASSERT_UINT32_WITHIN_MESSAGE(1000u, SONAR_RING_PERIOD_US, f.stamp_us - last_stamp,
                                              "frames still 96 ms apart");
        }
        last_stamp = f.stamp_us;
        seq++;
    }
    TEST_ASSERT_EQUAL_UINT16(0u, sonar_ring_fault_count(5));
    TEST_ASSERT_EQUAL_UINT16(0u, neighbour_violations);
}

/* A single sensor fires every slot; an HC-SR04 free-space echo (38 ms) outlasts the 32 ms slot, so
 * the ring waits for it to end before firing again, instead of seeing it high at the trigger. */
void test_sonar_ring_single_sensor_waits_for_free_space_echo_to_end(void)
{
    ring_setup(&SONAR_RING_1_SRF05);
    mode[0] = MODE_FREE;
    sonar_frame_t f;
    uint32_t frames = 0u;
    for (uint16_t k = 0; k < 1000u; k++) {
        run_for(500u, 250u);
        if (sonar_ring_snapshot(&f)) {
            frames++;
            TEST_ASSERT_EQUAL_UINT8_MESSAGE(SONAR_NO_ECHO, f.status[0], "free space in every frame");
        }
    }
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, sonar_ring_fault_count(0), "free space is not a fault");
    TEST_ASSERT_TRUE_MESSAGE(frames >= 5u, "at least 10 Hz over 0.5 s");
}

/* ---- schedule ---------------------------------------------------------- */

void test_sonar_ring_groups_keep_neighbours_apart_for_all_ring_sizes(void)
{
    for (uint8_t n = 1; n <= SONAR_RING_MAX; n++) {
        sonar_ring_cfg_t cfg = {SONAR_RING_12_SDLG.sensor, n};
        TEST_ASSERT_TRUE(sonar_ring_init(&cfg));
        TEST_ASSERT_TRUE_MESSAGE(sonar_ring_schedule_ok(), "neighbours share a group");
    }
    ring_setup(&SONAR_RING_12_SDLG);
    TEST_ASSERT_EQUAL_UINT8(0u, sonar_ring_group_of(0));
    TEST_ASSERT_EQUAL_UINT8(1u, sonar_ring_group_of(1));
    TEST_ASSERT_EQUAL_UINT8(0u, sonar_ring_group_of(9));
    TEST_ASSERT_EQUAL_UINT8(2u, sonar_ring_group_of(11));
}

void test_sonar_ring_schedule_never_fires_neighbours_within_30ms_over_3s(void)
{
    for (uint8_t i = 0; i < SONAR_RING_MAX; i++) {
        world_mm[i] = (uint16_t)(300u + 250u * i);
    }
    mode[4] = MODE_FREE;
    run_for(3000000UL, 700u); /* odd loop period: firings land off any neat grid */
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, neighbour_violations, "neighbour fired within 30 ms");
    TEST_ASSERT_TRUE_MESSAGE(min_neighbour_gap_us >= SONAR_NEIGHBOUR_GAP_US, "min neighbour gap below 30 ms");
    TEST_ASSERT_TRUE_MESSAGE(sim_sonar_trigger_count(0) >= 30u, "S0 fired at >= 10 Hz");
    TEST_ASSERT_TRUE_MESSAGE(sim_sonar_trigger_count(11) >= 30u, "S11 fired at >= 10 Hz");
    TEST_ASSERT_EQUAL_UINT16(0u, sonar_ring_guard_skips());
    /* The last triggers of the wrap pair are a full slot apart, too. */
    uint32_t d = sim_sonar_last_trigger_us(0) - sim_sonar_last_trigger_us(11);
    if ((int32_t)d < 0) {
        d = (uint32_t)(-(int32_t)d);
    }
    TEST_ASSERT_TRUE_MESSAGE(d >= SONAR_NEIGHBOUR_GAP_US, "S0/S11 last triggers too close");
}

void test_sonar_ring_schedule_keeps_gap_for_six_sensor_ring(void)
{
    ring_setup(&SONAR_RING_6_HCSR04);
    run_for(2000000UL, 1000u);
    TEST_ASSERT_EQUAL_UINT16(0u, neighbour_violations);
    TEST_ASSERT_TRUE(min_neighbour_gap_us >= SONAR_NEIGHBOUR_GAP_US);
    TEST_ASSERT_TRUE_MESSAGE(sonar_ring_frames_completed() >= 20u, "6-ring at >= 10 Hz");
}

void test_sonar_ring_full_12_ring_completes_at_least_10_hz(void)
{
    /* Worst case: every sensor waits for the full max-range timeout. */
    for (uint8_t i = 0; i < SONAR_RING_MAX; i++) {
        mode[i] = MODE_FREE;
    }
    uint32_t t0 = hal_time_us();
    uint32_t last_stamp = 0u, worst_gap = 0u;
    uint32_t frames = 0u;
    sonar_frame_t f;
    for (uint16_t k = 0; k < 600u; k++) {
        run_for(5000u, 500u); /* poll often enough to see every pass */
        if (sonar_ring_snapshot(&f)) {
            TEST_ASSERT_EQUAL_UINT32_MESSAGE(frames + 1u, f.seq, "missed a pass");
            if (frames > 0u && f.stamp_us - last_stamp > worst_gap) {
                worst_gap = f.stamp_us - last_stamp;
            }
            last_stamp = f.stamp_us;
            frames = f.seq;
        }
    }
    uint32_t elapsed_us = hal_time_us() - t0;
    TEST_ASSERT_EQUAL_UINT32(3000000UL, elapsed_us);
    TEST_ASSERT_TRUE_MESSAGE(frames >= 30u, "fewer than 30 full rings in 3 s");
    TEST_ASSERT_TRUE_MESSAGE(worst_gap <= 100000UL, "ring-to-ring period above 100 ms");
    for (uint8_t i = 0; i < SONAR_RING_MAX; i++) {
        TEST_ASSERT_EQUAL_UINT8(SONAR_NO_ECHO, f.status[i]);
    }
}

/* ---- filter and frame -------------------------------------------------- */

void test_sonar_ring_median_filter_drops_single_spike(void)
{
    sonar_frame_t f;
    world_mm[1] = 1000u;
    run_for(300000UL, 250u); /* three passes at 1 m */
    TEST_ASSERT_TRUE(sonar_ring_frames_completed() >= 3u);
    uint32_t seq = sonar_ring_frames_completed();
    world_mm[1] = 150u; /* one spurious short echo */
    while (sonar_ring_frames_completed() == seq) {
        run_for(1000u, 250u);
    }
    world_mm[1] = 1000u;
    sonar_ring_snapshot(&f);
    TEST_ASSERT_EQUAL_UINT8(SONAR_VALID, f.status[1]);
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(5u, 1000u, f.ranges_mm[1], "spike passed the median");
    /* A lasting change does get through after two passes. */
    world_mm[1] = 500u;
    seq = sonar_ring_frames_completed();
    while (sonar_ring_frames_completed() < seq + 2u) {
        run_for(1000u, 250u);
    }
    sonar_ring_snapshot(&f);
    TEST_ASSERT_UINT16_WITHIN_MESSAGE(5u, 500u, f.ranges_mm[1], "real step follows");
}

void test_sonar_ring_snapshot_flags_new_frame_once(void)
{
    sonar_frame_t f;
    TEST_ASSERT_FALSE_MESSAGE(sonar_ring_snapshot(&f), "nothing before the first pass");
    TEST_ASSERT_EQUAL_UINT32(0u, f.seq);
    TEST_ASSERT_EQUAL_UINT8(SONAR_STALE, f.status[0]);
    run_for(100000UL, 250u);
    TEST_ASSERT_TRUE(sonar_ring_snapshot(&f));
    TEST_ASSERT_EQUAL_UINT32(1u, f.seq);
    TEST_ASSERT_EQUAL_UINT8(12u, f.count);
    TEST_ASSERT_FALSE_MESSAGE(sonar_ring_snapshot(&f), "same pass reported twice");
}

void test_sonar_ring_runs_across_timer_wrap(void)
{
    sim_time_set_us(0xFFFFFFFFUL - 150000UL);
    ring_setup(&SONAR_RING_12_SDLG);
    world_mm[0] = 800u;
    run_for(1000000UL, 500u);
    sonar_frame_t f;
    sonar_ring_snapshot(&f);
    TEST_ASSERT_TRUE_MESSAGE(f.seq >= 10u, "ring stalled at the wrap");
    TEST_ASSERT_EQUAL_UINT8(SONAR_VALID, f.status[0]);
    TEST_ASSERT_UINT16_WITHIN(5u, 800u, f.ranges_mm[0]);
    TEST_ASSERT_EQUAL_UINT16(0u, neighbour_violations);
    TEST_ASSERT_EQUAL_UINT16(0u, sonar_ring_fault_count(0));
}

void test_sonar_ring_presets_match_reference_layouts(void)
{
    const UNITS_ROM sonar_cfg_t *c = SONAR_RING_12_SDLG.sensor;
    TEST_ASSERT_EQUAL_UINT8(12u, SONAR_RING_12_SDLG.count);
    TEST_ASSERT_EQUAL_INT16_MESSAGE(0, c[0].bearing_cdeg, "S0 front");
    TEST_ASSERT_EQUAL_INT16_MESSAGE(18000, c[6].bearing_cdeg, "S6 back");
    TEST_ASSERT_EQUAL_INT16_MESSAGE(9000, c[3].bearing_cdeg, "S3 left");
    for (uint8_t i = 0; i < 12u; i++) {
        int32_t d = (int32_t)c[(i + 1u) % 12u].bearing_cdeg - c[i].bearing_cdeg;
        while (d < 0) {
            d += 36000;
        }
        TEST_ASSERT_EQUAL_INT32_MESSAGE(3000, d, "30 deg spacing CCW");
    }
    TEST_ASSERT_EQUAL_UINT8(6u, SONAR_RING_6_HCSR04.count);
    TEST_ASSERT_EQUAL_UINT8(1u, SONAR_RING_1_SRF05.count);
    TEST_ASSERT_FALSE(sonar_ring_init(0));
}

#if defined(__AVR_ATmega2560__)
/* ---- the ATmega2560's hand-written echo vector (hal/avr/echo_pcint_avr.S) -----------------
 * Under simavr: the echo ports driven as outputs (PINB / PIND follow), Timer5 running at
 * clk/1 (a stamp between the counts read just before and just after), the vector called as the hardware would (PCINT0 and INT0 share its body).
 * Each call must append exactly one record (PINB, PIND, TCNT5 low, high) and advance the head
 * by 4; hal_sonar_poll() on the board decodes these records (the SIL tests run it). */
#include <avr/io.h>

#include "../../lib/hal/avr/echo_queue_avr.h"

extern uint8_t hal_avr_echo_q[ECHO_Q_BYTES];
extern volatile uint8_t hal_avr_echo_head;

static void test_sonar_ring_avr_echo_vector_queues_lines_and_timer5_stamp(void)
{
    uint8_t tccr5b = TCCR5B;
    TCCR5B = (uint8_t)(1u << CS50); /* clk/1: every cycle visible */
    DDRB = 0xFFu;
    DDRD = 0x0Fu;
    uint8_t head0 = hal_avr_echo_head;
    const uint8_t n = (uint8_t)(ECHO_Q_RECORDS + 3u); /* wraps the queue */
    for (uint8_t k = 0; k < n; k++) {
        uint8_t pinb = (uint8_t)(k * 37u + 1u), pind = (uint8_t)(k & 0x0Fu);
        PORTB = pinb;
        PORTD = pind;
        uint8_t sreg = SREG;
        uint16_t before = TCNT5;
        if (k & 1u) {
            __asm__ volatile("call __vector_1" ::: "memory"); /* INT0_vect; its reti sets I */
        } else {
            __asm__ volatile("call __vector_9" ::: "memory"); /* PCINT0_vect */
        }
        uint16_t after = TCNT5;
        SREG = sreg;
        uint8_t head = (uint8_t)(head0 + 4u * k);
        TEST_ASSERT_EQUAL_HEX8_MESSAGE((uint8_t)(head + 4u), hal_avr_echo_head, "one record per call");
        const uint8_t *r = &hal_avr_echo_q[head & (ECHO_Q_BYTES - 4u)];
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(pinb, r[0], "PINB: echoes 0..7");
        TEST_ASSERT_EQUAL_HEX8_MESSAGE(pind, r[1] & 0x0Fu, "PIND: echoes 8..11");
        uint16_t stamp = (uint16_t)(r[2] | ((uint16_t)r[3] << 8));
        TEST_ASSERT_TRUE_MESSAGE((uint16_t)(stamp - before) > 0u, "Timer5 stamp after the call");
        TEST_ASSERT_TRUE_MESSAGE((uint16_t)(after - stamp) > 0u &&
                                 (uint16_t)(after - stamp) < (uint16_t)(after - before), "Timer5 stamp before return");
    }
    PORTB = 0u;
    PORTD = 0u;
    DDRB = 0u;
    DDRD = 0u;
    TCCR5B = tccr5b;
}
#endif

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_sonar_ring_mm_from_echo_us_uses_343_m_s_round_trip);
    RUN_TEST(test_sonar_ring_step_measures_near_target_at_100mm_within_5mm);
    RUN_TEST(test_sonar_ring_step_measures_far_target_at_3m_within_10mm);
    RUN_TEST(test_sonar_ring_step_reports_no_echo_when_pulse_runs_past_max_range);
    RUN_TEST(test_sonar_ring_step_reads_short_echo_right_after_trigger_as_valid_10mm);
    RUN_TEST(test_sonar_ring_step_reports_fault_and_counts_when_no_rising_edge);
    RUN_TEST(test_sonar_ring_step_reports_fault_when_echo_line_stuck_high);
    RUN_TEST(test_sonar_ring_step_reports_fault_in_every_frame_when_echo_line_goes_high_and_stays);
    RUN_TEST(test_sonar_ring_step_reports_fault_when_echo_line_high_from_power_on);
    RUN_TEST(test_sonar_ring_frame_holds_one_pass_while_last_group_free_space_echo_ends);
    RUN_TEST(test_sonar_ring_single_sensor_waits_for_free_space_echo_to_end);
    RUN_TEST(test_sonar_ring_groups_keep_neighbours_apart_for_all_ring_sizes);
    RUN_TEST(test_sonar_ring_schedule_never_fires_neighbours_within_30ms_over_3s);
    RUN_TEST(test_sonar_ring_schedule_keeps_gap_for_six_sensor_ring);
    RUN_TEST(test_sonar_ring_full_12_ring_completes_at_least_10_hz);
    RUN_TEST(test_sonar_ring_median_filter_drops_single_spike);
    RUN_TEST(test_sonar_ring_snapshot_flags_new_frame_once);
    RUN_TEST(test_sonar_ring_runs_across_timer_wrap);
    RUN_TEST(test_sonar_ring_presets_match_reference_layouts);
#if defined(__AVR_ATmega2560__)
    RUN_TEST(test_sonar_ring_avr_echo_vector_queues_lines_and_timer5_stamp);
#endif
    return UNITY_END();
}
