/* Unity tests for lib/encoder: quadrature decode, Hall counting, wrap
 * handling, both speed estimators, snapshot and health flags. */
#include <stdint.h>

#include "encoder.h"
#include "hal.h"
#include "sim/hal_sim.h"
#include "unity.h"

#define QUAD_NM 50000u /* 50 um per count: easy numbers */
/* Reference car (ref 003): 16 magnets, 69 mm wheel -> pi*69/16 mm per pulse. */
#define HALL_NM 13548118u

static uint8_t s_ab[ENCODER_MAX]; /* current simulated A/B levels per wheel */

static encoder_cfg_t quad_cfg(uint8_t invert)
{
    encoder_cfg_t c = {0};
    c.mode = ENCODER_MODE_QUAD_X4;
    c.invert = invert;
    c.travel_per_count_nm = QUAD_NM;
    return c;
}

static encoder_cfg_t hall_cfg(void)
{
    encoder_cfg_t c = {0};
    c.mode = ENCODER_MODE_HALL;
    c.counts_per_wheel_rev = 16u;
    c.wheel_diameter_um = 69000u;
    return c;
}

static void init_quad(uint8_t invert)
{
    encoder_cfg_t c[2] = {quad_cfg(invert), quad_cfg(0)};
    TEST_ASSERT_TRUE_MESSAGE(encoder_init(2, c), "init quad");
}

static void init_hall(void)
{
    encoder_cfg_t c[1] = {hall_cfg()};
    TEST_ASSERT_TRUE_MESSAGE(encoder_init(1, c), "init hall");
}

/* n quadrature steps on wheel idx, forward if n > 0 (A leads B: 0,2,3,1),
 * backward otherwise; time advances dt_us before each edge. */
static void quad_steps(uint8_t idx, int32_t n, uint32_t dt_us)
{
    static const uint8_t FWD[4] = {2u, 0u, 3u, 1u}; /* next state after 0,1,2,3 going forward */
    static const uint8_t BWD[4] = {1u, 3u, 0u, 2u};
    int32_t k = n < 0 ? -n : n;
    for (int32_t i = 0; i < k; i++) {
        sim_time_advance_us(dt_us);
        s_ab[idx] = n > 0 ? FWD[s_ab[idx]] : BWD[s_ab[idx]];
        sim_encoder_edge(idx, s_ab[idx]);
    }
}

/* One Hall pulse on wheel idx: rising edge now, falling edge 1 ms later. */
static void hall_pulse(uint8_t idx)
{
    sim_encoder_edge(idx, 2u);
    sim_time_advance_us(1000u);
    sim_encoder_edge(idx, 0u);
}

void setUp(void)
{
    sim_reset();
    for (uint8_t i = 0; i < ENCODER_MAX; i++) {
        s_ab[i] = 0u;
    }
    init_quad(0);
}

void tearDown(void) {}

/* ---- decoding ---------------------------------------------------------- */

static void test_encoder_edge_counts_up_when_a_leads_b(void)
{
    encoder_snapshot_t s;
    quad_steps(0, 40, 100u);
    TEST_ASSERT_TRUE(encoder_snapshot(0, &s));
    TEST_ASSERT_EQUAL_INT32_MESSAGE(40, s.count, "10 full cycles forward");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(40u, s.edges, "every edge counted in edges");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(0u, s.errors, "no errors");
    TEST_ASSERT_EQUAL_INT8(1, s.dir);
}

static void test_encoder_edge_counts_down_when_b_leads_a(void)
{
    encoder_snapshot_t s;
    quad_steps(0, -37, 100u);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-37, s.count, "backward");
    TEST_ASSERT_EQUAL_INT8(-1, s.dir);
    quad_steps(0, 12, 100u);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-25, s.count, "reversal counts back up");
    TEST_ASSERT_EQUAL_UINT32(49u, s.edges);
}

static void test_encoder_edge_counts_down_when_invert_set(void)
{
    encoder_snapshot_t s;
    init_quad(1);
    quad_steps(0, 8, 100u);
    quad_steps(1, 8, 100u);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-8, s.count, "inverted wheel");
    (void)encoder_snapshot(1, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(8, s.count, "other wheel unaffected");
}

static void test_encoder_edge_counts_illegal_jump_as_error_not_motion(void)
{
    encoder_snapshot_t s;
    quad_steps(0, 3, 100u); /* 0 -> 2 -> 3 -> 1 */
    sim_encoder_edge(0, 2u); /* 1 -> 2: both lines changed */
    sim_encoder_edge(0, 1u); /* 2 -> 1: again */
    sim_encoder_edge(0, 1u); /* 1 -> 1: repeated level, no motion, no error, no edge */
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(3, s.count, "illegal jumps do not move the count");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(2u, s.errors, "two illegal jumps");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(5u, s.edges, "3 steps + 2 jumps; the repeated level is no edge");
    quad_steps(0, 1, 100u); /* 1 -> 0: decoding goes on from the levels after the jumps */
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32(4, s.count);
}

static void test_encoder_edge_ignores_out_of_range_index(void)
{
    encoder_snapshot_t s;
    encoder_isr_edge(ENCODER_MAX, 2u, 0u);
    encoder_isr_edge(200u, 2u, 0u);
    TEST_ASSERT_FALSE(encoder_snapshot(ENCODER_MAX, &s));
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_UINT32(0u, s.edges);
}

/* ---- Hall mode --------------------------------------------------------- */

static void test_encoder_hall_counts_one_per_pulse(void)
{
    encoder_snapshot_t s;
    init_hall();
    for (uint8_t i = 0; i < 5u; i++) {
        sim_time_advance_us(10000u);
        hall_pulse(0);
    }
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(5, s.count, "one count per magnet");
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(10u, s.edges, "rising and falling edges");
    TEST_ASSERT_EQUAL_UINT32(HALL_NM, encoder_travel_per_count_nm(0));
}

static void test_encoder_hall_direction_follows_hint(void)
{
    encoder_snapshot_t s;
    init_hall();
    hall_pulse(0);
    hall_pulse(0);
    encoder_set_direction_hint(0, -1);
    hall_pulse(0);
    hall_pulse(0);
    hall_pulse(0);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-1, s.count, "2 forward, 3 backward");
    encoder_set_direction_hint(0, 0); /* zero keeps the last direction (coasting) */
    hall_pulse(0);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-2, s.count, "hint 0 keeps backward");
    encoder_set_direction_hint(0, 5);
    hall_pulse(0);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-1, s.count, "positive hint counts forward");
}

/* ---- wrap handling ----------------------------------------------------- */

static void test_encoder_update_delta_is_right_across_int32_count_wrap(void)
{
    encoder_snapshot_t s;
    encoder_motion_t m;
    encoder_set_count(0, INT32_MAX - 2);
    sim_time_advance_us(20000u);
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(0, m.delta_um, "set_count is not motion");
    quad_steps(0, 8, 100u);
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(INT32_MIN + 5, s.count, "count wraps modulo 2^32");
    sim_time_advance_us(19200u);
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(8 * 50, m.delta_um, "8 counts forward across the wrap");
    quad_steps(0, -10, 100u);
    sim_time_advance_us(19000u);
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-10 * 50, m.delta_um, "10 counts back across the wrap");
}

static void test_encoder_update_speed_is_right_across_micros_wrap(void)
{
    encoder_motion_t m;
    encoder_snapshot_t s;
    sim_time_set_us(0xFFFFFFFFu - 45000u); /* clock wraps during the test */
    init_quad(0);
    /* 2 counts per 20 ms tick, one every 10 ms: 5 mm/s, period method. */
    for (uint8_t tick = 0; tick < 5u; tick++) {
        quad_steps(0, 2, 10000u);
        encoder_update(hal_time_us());
    }
    TEST_ASSERT_TRUE_MESSAGE(hal_time_us() < 100000u, "clock really wrapped");
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_UINT32_MESSAGE(20000u, s.span_us, "period across the wrap: 20 ms ...");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(2u, s.span_counts, "... over 2 counts");
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(5, m.speed_mm_s, "50 um / 10 ms");
    TEST_ASSERT_EQUAL_UINT8(ENCODER_SPEED_PERIOD, m.method);
    TEST_ASSERT_EQUAL_INT32(100, m.delta_um);
}

/* ---- speed estimators -------------------------------------------------- */

static void test_encoder_update_period_method_at_one_pulse_per_200ms(void)
{
    encoder_motion_t m;
    int32_t min_decay = INT32_MAX;
    init_hall();
    /* Pulses at t = 100, 300, ..., 1900 ms; updates every 20 ms to 2.3 s. */
    for (uint16_t t_ms = 1; t_ms <= 2300u; t_ms++) {
        sim_time_advance_us(1000u);
        if (t_ms <= 1900u && t_ms % 200u == 100u) {
            sim_encoder_edge(0, 2u);
        } else if (t_ms <= 1901u && t_ms % 200u == 101u) {
            sim_encoder_edge(0, 0u);
        }
        if (t_ms % 20u == 0u) {
            encoder_update(hal_time_us());
            encoder_motion(0, &m);
            if (t_ms >= 400u && t_ms <= 1900u) {
                /* 13.548 mm / 200 ms = 67.7 mm/s between and at pulses. */
                TEST_ASSERT_INT32_WITHIN_MESSAGE(1, 68, m.speed_mm_s, "period method");
                TEST_ASSERT_EQUAL_UINT8(ENCODER_SPEED_PERIOD, m.method);
            } else if (t_ms > 2100u && t_ms < 2150u) {
                TEST_ASSERT_EQUAL_UINT8_MESSAGE(ENCODER_SPEED_DECAY, m.method, "overdue pulse");
                TEST_ASSERT_TRUE_MESSAGE(m.speed_mm_s < 68 && m.speed_mm_s > 0, "decaying");
                if (m.speed_mm_s < min_decay) {
                    min_decay = m.speed_mm_s;
                }
            } else if (t_ms >= 2160u) {
                TEST_ASSERT_EQUAL_INT32_MESSAGE(0, m.speed_mm_s, "stopped after 250 ms");
                TEST_ASSERT_EQUAL_UINT8(ENCODER_SPEED_STOPPED, m.method);
                TEST_ASSERT_BITS_HIGH(ENCODER_F_STOPPED, m.flags);
            }
        }
    }
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, 13548 / 240, min_decay, "bound 1 count / 240 ms");
}

static void test_encoder_update_period_method_is_negative_backward(void)
{
    encoder_motion_t m;
    for (uint8_t tick = 0; tick < 4u; tick++) {
        quad_steps(0, -1, 20000u); /* one count per 20 ms backward: -2.5 mm/s */
        encoder_update(hal_time_us());
    }
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_INT32(-50, m.delta_um);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(1, -3, m.speed_mm_s, "-2.5 mm/s rounds to -2 or -3");
    TEST_ASSERT_TRUE(m.speed_mm_s < 0);
    TEST_ASSERT_EQUAL_UINT8(ENCODER_SPEED_PERIOD, m.method);
}

static void test_encoder_update_count_method_at_40khz_edges(void)
{
    encoder_motion_t m;
    encoder_update(hal_time_us());
    for (uint8_t tick = 0; tick < 3u; tick++) {
        quad_steps(0, 800, 25u); /* 40 kHz for one 20 ms tick */
        quad_steps(1, -800, 0u); /* wheel 1 backward at the same instants */
        encoder_update(hal_time_us());
    }
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_UINT8(ENCODER_SPEED_COUNT, m.method);
    TEST_ASSERT_EQUAL_INT32_MESSAGE(800L * 50L, m.delta_um, "40 mm per tick");
    TEST_ASSERT_INT32_WITHIN_MESSAGE(2, 2000, m.speed_mm_s, "40k counts/s * 50 um");
    encoder_motion(1, &m);
    TEST_ASSERT_INT32_WITHIN_MESSAGE(2, -2000, m.speed_mm_s, "backward wheel");
}

static void test_encoder_update_uses_period_below_crossover_and_count_above(void)
{
    encoder_motion_t m;
    encoder_update(hal_time_us());
    quad_steps(0, 7, 2857u); /* 7 counts in 20 ms: below crossover 8 */
    sim_time_advance_us(20000u - 7u * 2857u);
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(ENCODER_SPEED_COUNT, m.method, "first counts of a run: no period yet");
    quad_steps(0, 7, 2857u);
    sim_time_advance_us(20000u - 7u * 2857u);
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(ENCODER_SPEED_PERIOD, m.method, "7 counts per tick");
    TEST_ASSERT_INT32_WITHIN(1, 17, m.speed_mm_s); /* 50 um / 2.857 ms */
    quad_steps(0, 8, 2500u); /* 8 counts in 20 ms */
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(ENCODER_SPEED_COUNT, m.method, "8 counts per tick");
    TEST_ASSERT_INT32_WITHIN(1, 20, m.speed_mm_s); /* 400 um / 20 ms */
}

static void test_encoder_update_distance_keeps_sub_micrometre_fraction(void)
{
    encoder_motion_t m;
    int32_t total_um = 0;
    init_hall();
    for (uint16_t i = 0; i < 1000u; i++) {
        sim_time_advance_us(5000u);
        hall_pulse(0);
        encoder_update(hal_time_us());
        encoder_motion(0, &m);
        total_um += m.delta_um;
    }
    /* 1000 * 13548.118 um = 13548118 um; per-update rounding must not add up. */
    TEST_ASSERT_INT32_WITHIN_MESSAGE(2, 13548118, total_um, "1000 pulses");
}

/* ---- snapshot and health ------------------------------------------------ */

/* Reference travel of the wide case (|dc| >= 2^15 or >= 256 mm per count): the 64-bit formula
 * the firmware had before it was done in 32-bit halves. */
static int32_t ref_travel_um(int32_t dc, uint32_t nm, uint8_t *resid)
{
    uint32_t um_q8 = (uint32_t)(((uint64_t)nm * 256u + 500u) / 1000u);
    int64_t acc = (int64_t)dc * (int64_t)um_q8 + (int64_t)*resid;
    *resid = (uint8_t)(acc & 0xFF);
    acc >>= 8;
    return acc > INT32_MAX ? INT32_MAX : acc < INT32_MIN ? INT32_MIN : (int32_t)acc;
}

static void test_encoder_update_wide_travel_matches_the_64_bit_formula(void)
{
    /* 3.999999997 m per count: every update takes the wide path; 600 counts (2.4 km) saturate at
     * INT32_MAX, 530 back (2.12 km) just do not, 600 back saturate at INT32_MIN (whose magnitude the
     * speed estimate takes: undefined behaviour as a signed negation, caught by UBSan natively) */
    static const int16_t BURSTS[] = {3, -5, 1, 0, -1, 7, 600, -530, 2, -2, -600, 4};
    const uint32_t nm = 3999999997u;
    encoder_cfg_t c = quad_cfg(0);
    c.travel_per_count_nm = nm;
    TEST_ASSERT_TRUE(encoder_init(1, &c));
    uint8_t resid = 0u;
    for (uint8_t i = 0; i < sizeof BURSTS / sizeof BURSTS[0]; i++) {
        encoder_motion_t m;
        quad_steps(0, BURSTS[i], 10u);
        sim_time_advance_us(20000u);
        encoder_update(hal_time_us());
        encoder_motion(0, &m);
        TEST_ASSERT_EQUAL_INT32(ref_travel_um(BURSTS[i], nm, &resid), m.delta_um);
    }
}

static void test_encoder_snapshot_copies_record_and_restores_irq_state(void)
{
    encoder_snapshot_t s;
    sim_time_set_us(5000u);
    quad_steps(0, 2, 300u);
    TEST_ASSERT_FALSE(sim_irq_masked());
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_FALSE_MESSAGE(sim_irq_masked(), "interrupts re-enabled");
    TEST_ASSERT_EQUAL_INT32(2, s.count);
    TEST_ASSERT_EQUAL_UINT32(5600u, s.last_edge_us);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(0u, s.span_counts, "one stamped step of the run so far");
    quad_steps(0, 3, 400u); /* 1200 us over 3 steps since the last one seen */
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_EQUAL_INT32(5, s.count);
    TEST_ASSERT_EQUAL_UINT32(6800u, s.last_edge_us);
    TEST_ASSERT_EQUAL_UINT32(1200u, s.span_us);
    TEST_ASSERT_EQUAL_UINT16(3u, s.span_counts);
    TEST_ASSERT_EQUAL_INT8(1, s.dir);
    hal_irq_state_t st = hal_irq_save();
    (void)encoder_snapshot(0, &s);
    TEST_ASSERT_TRUE_MESSAGE(sim_irq_masked(), "a masked caller stays masked");
    hal_irq_restore(st);
}

static void test_encoder_update_sets_fault_on_high_error_ratio_and_clears(void)
{
    encoder_motion_t m;
    /* 48 good edges + 16 illegal jumps: 25% errors in a 64-edge window. */
    quad_steps(0, 48, 50u);
    for (uint8_t i = 0; i < 8u; i++) {
        uint8_t jump = (uint8_t)(s_ab[0] ^ 3u);
        sim_encoder_edge(0, jump);
        sim_encoder_edge(0, s_ab[0]);
    }
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_BITS_HIGH_MESSAGE(ENCODER_F_ERROR_RATIO, m.flags, "25% illegal");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x01u, encoder_faults(), "wheel 0 only");
    quad_steps(0, 64, 50u);
    sim_time_advance_us(20000u);
    encoder_update(hal_time_us());
    encoder_motion(0, &m);
    TEST_ASSERT_BITS_LOW_MESSAGE(ENCODER_F_ERROR_RATIO, m.flags, "clean window clears");
    TEST_ASSERT_EQUAL_HEX8(0x00u, encoder_faults());
}

static void test_encoder_update_tolerates_rare_errors(void)
{
    quad_steps(0, 62, 50u);
    sim_encoder_edge(0, (uint8_t)(s_ab[0] ^ 3u)); /* one glitch and back */
    sim_encoder_edge(0, s_ab[0]);
    encoder_update(hal_time_us());
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x00u, encoder_faults(), "2 of 64 is not a fault");
}

/* ---- configuration ------------------------------------------------------ */

static void test_encoder_counts_per_wheel_rev_folds_x4_and_gear(void)
{
    TEST_ASSERT_EQUAL_UINT32(60000u, encoder_counts_per_wheel_rev(500u, ENCODER_MODE_QUAD_X4, 30u, 1u));
    TEST_ASSERT_EQUAL_UINT32(16u, encoder_counts_per_wheel_rev(16u, ENCODER_MODE_HALL, 1u, 1u));
    TEST_ASSERT_EQUAL_UINT32(4267u, encoder_counts_per_wheel_rev(64u, ENCODER_MODE_QUAD_X4, 50u, 3u));
    TEST_ASSERT_EQUAL_UINT32(0u, encoder_counts_per_wheel_rev(64u, ENCODER_MODE_QUAD_X4, 50u, 0u));
}

static void test_encoder_init_rejects_config_without_travel(void)
{
    encoder_cfg_t c[2] = {quad_cfg(0), quad_cfg(0)};
    encoder_motion_t m;
    c[1].travel_per_count_nm = 0u; /* and no diameter/counts */
    TEST_ASSERT_FALSE(encoder_init(2, c));
    encoder_motion(1, &m);
    TEST_ASSERT_BITS_HIGH(ENCODER_F_UNCONFIGURED, m.flags);
    TEST_ASSERT_EQUAL_UINT32(QUAD_NM, encoder_travel_per_count_nm(0));
    TEST_ASSERT_EQUAL_UINT32(0u, encoder_travel_per_count_nm(1));
}

#if defined(__AVR_ATmega2560__)
/* ---- the ATmega2560's hand-written PORTK vector (hal/avr/encoder_pcint_avr.S) -----------
 * Under simavr: PORTK driven as outputs (PINK follows), the vector called like the hardware
 * would after each change; the loop side must read the same as from the generic hook. */
#include <avr/io.h>

static uint8_t s_pink;

static void pink_set(uint8_t levels)
{
    s_pink = levels;
    PORTK = levels;
    uint8_t sreg = SREG;
    __asm__ volatile("call __vector_11" ::: "memory"); /* PCINT2_vect; its reti sets I */
    SREG = sreg;
}

/* n quadrature steps of encoder idx on PORTK (A = PK(2 idx), B = PK(2 idx + 1)). */
static void pink_steps(uint8_t idx, int16_t n)
{
    static const uint8_t FWD[4] = {2u, 0u, 3u, 1u}; /* as quad_steps(), ab = (A << 1) | B */
    static const uint8_t BWD[4] = {1u, 3u, 0u, 2u};
    uint8_t sh = (uint8_t)(2u * idx);
    for (int16_t k = 0; k < (n < 0 ? -n : n); k++) {
        uint8_t pins = (uint8_t)((s_pink >> sh) & 3u);
        uint8_t ab = (uint8_t)(((pins & 1u) << 1) | (pins >> 1));
        ab = n > 0 ? FWD[ab] : BWD[ab];
        pins = (uint8_t)(((ab & 1u) << 1) | (ab >> 1));
        pink_set((uint8_t)((s_pink & (uint8_t)~(3u << sh)) | (uint8_t)(pins << sh)));
    }
}

static void test_encoder_avr_vector_decodes_four_encoders(void)
{
    encoder_cfg_t c[4] = {quad_cfg(0), quad_cfg(0), quad_cfg(1), quad_cfg(0)};
    encoder_snapshot_t s;
    TEST_ASSERT_TRUE(encoder_init(4, c));
    DDRK = 0xFFu;
    PORTK = 0u;
    s_pink = 0u;
    GPIOR1 = PINK; /* what hal_encoder_attach() seeds on the board */
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, PINK, "PINK follows PORTK");

    pink_steps(3, 300);  /* low byte of the counter wraps once (carry path) */
    pink_steps(1, -37);
    pink_steps(2, 9);    /* wheel 2 is inverted */
    pink_steps(0, 2);
    pink_set((uint8_t)(s_pink ^ 0x03u)); /* encoder 0: both lines at once, illegal */
    pink_set((uint8_t)(s_pink ^ 0x03u)); /* and back: illegal again */
    pink_set(s_pink);                    /* nothing changed */
    pink_set((uint8_t)(s_pink ^ 0x11u)); /* A of encoders 0 and 2 in one interrupt */
    (void)encoder_snapshot(3, &s);
    TEST_ASSERT_EQUAL_INT32(300, s.count);
    TEST_ASSERT_EQUAL_UINT32(300u, s.edges);
    TEST_ASSERT_EQUAL_INT8(1, s.dir);
    (void)encoder_snapshot(1, &s);
    TEST_ASSERT_EQUAL_INT32(-37, s.count);
    TEST_ASSERT_EQUAL_INT8(-1, s.dir);
    (void)encoder_snapshot(2, &s);
    /* 9 steps forward end at ab = 2; A toggling (2 -> 0) is a backward step, +1 when inverted */
    TEST_ASSERT_EQUAL_INT32_MESSAGE(-9 + 1, s.count, "inverted wheel, then the shared interrupt");
    (void)encoder_snapshot(0, &s);
    /* 2 steps forward end at ab = 3; after the two jumps A toggles: 3 -> 1, forward */
    TEST_ASSERT_EQUAL_INT32_MESSAGE(2 + 1, s.count, "illegal jumps do not count; the shared step does");
    TEST_ASSERT_EQUAL_UINT32(2u, s.errors);
    TEST_ASSERT_EQUAL_UINT32(5u, s.edges);
    DDRK = 0u;
    PORTK = 0u;
}
#endif

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_encoder_edge_counts_up_when_a_leads_b);
    RUN_TEST(test_encoder_edge_counts_down_when_b_leads_a);
    RUN_TEST(test_encoder_edge_counts_down_when_invert_set);
    RUN_TEST(test_encoder_edge_counts_illegal_jump_as_error_not_motion);
    RUN_TEST(test_encoder_edge_ignores_out_of_range_index);
    RUN_TEST(test_encoder_hall_counts_one_per_pulse);
    RUN_TEST(test_encoder_hall_direction_follows_hint);
    RUN_TEST(test_encoder_update_delta_is_right_across_int32_count_wrap);
    RUN_TEST(test_encoder_update_speed_is_right_across_micros_wrap);
    RUN_TEST(test_encoder_update_period_method_at_one_pulse_per_200ms);
    RUN_TEST(test_encoder_update_period_method_is_negative_backward);
    RUN_TEST(test_encoder_update_count_method_at_40khz_edges);
    RUN_TEST(test_encoder_update_uses_period_below_crossover_and_count_above);
    RUN_TEST(test_encoder_update_distance_keeps_sub_micrometre_fraction);
    RUN_TEST(test_encoder_update_wide_travel_matches_the_64_bit_formula);
    RUN_TEST(test_encoder_snapshot_copies_record_and_restores_irq_state);
    RUN_TEST(test_encoder_update_sets_fault_on_high_error_ratio_and_clears);
    RUN_TEST(test_encoder_update_tolerates_rare_errors);
    RUN_TEST(test_encoder_counts_per_wheel_rev_folds_x4_and_gear);
    RUN_TEST(test_encoder_init_rejects_config_without_travel);
#if defined(__AVR_ATmega2560__)
    RUN_TEST(test_encoder_avr_vector_decodes_four_encoders);
#endif
    return UNITY_END();
}
