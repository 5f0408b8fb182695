/*
 * The ATmega2560 encoder inputs of the AVR HAL backend (PORTK, PCINT2, the hand-written vector of
 * hal/avr/encoder_pcint_avr.S), under simavr (megaatmega2560 env only: the other envs list this
 * suite in test_ignore). Unit-test builds link the sim backend as "the HAL", so the real backend is
 * compiled into this file under other names (avr_hal_*) and the two coexist.
 *
 * hal.h: a Hall wheel's B reads 0. The checks read what hal_encoder_attach() wrote (PORTK pull-ups,
 * DDRK, PCMSK2), the level PINK then shows for an undriven B line, and what the vector counts
 * from a Hall pulse: with B at 0, the rising edge of A is the raw-forward step (encoder_isr.h).
 */
#include "../hal_avr_under_test.h"

#include <string.h>
#include <unity.h>

#include "encoder_isr.h"

static void no_hook(uint8_t idx, uint8_t ab, uint32_t t_us)
{
    (void)idx;
    (void)ab;
    (void)t_us;
}

/* PORTK changed: run the PCINT2 vector as the hardware would (its reti sets I: restore SREG). */
static void pcint2(void)
{
    uint8_t sreg = SREG;
    __asm__ volatile("call __vector_11" ::: "memory");
    SREG = sreg;
}

void setUp(void)
{
    PCICR = 0u; /* the vector runs only when a test calls it */
    DDRK = 0u;
    PORTK = 0u;
    memset(encoder_isr_state, 0, sizeof encoder_isr_state);
}

void tearDown(void)
{
    PCICR = 0u;
    DDRK = 0u;
    PORTK = 0u;
}

static void test_encoder_attach_hall_wheel_leaves_b_without_pull_up(void)
{
    avr_hal_encoder_attach(2u, 0x01u, no_hook); /* wheel 0 Hall, wheel 1 quadrature */
    PCICR = 0u;
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x00u, DDRK & 0x0Fu, "all four lines inputs");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x0Du, PORTK & 0x0Fu, "pull-ups: wheel 0 A, wheel 1 A and B; not wheel 0 B");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x0Du, PCMSK2, "no pin-change interrupt from an unused B");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x00u, PINK & 0x02u, "wheel 0 B reads 0");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x0Du, PINK & 0x0Du, "pulled-up lines read 1");
}

static void test_encoder_attach_quadrature_wheels_pull_up_both_lines(void)
{
    avr_hal_encoder_attach(4u, 0x00u, no_hook);
    PCICR = 0u;
    TEST_ASSERT_EQUAL_HEX8(0xFFu, PORTK);
    TEST_ASSERT_EQUAL_HEX8(0xFFu, PCMSK2);
    avr_hal_encoder_attach(4u, 0x0Au, no_hook); /* wheels 1 and 3 Hall */
    PCICR = 0u;
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0x77u, PORTK, "B of wheels 1, 3 (PK3, PK7) without pull-up");
    TEST_ASSERT_EQUAL_HEX8(0x77u, PCMSK2);
}

/* A Hall pulse on wheel 0's A with B left alone: rising edges are raw-forward steps. */
static void test_hall_pulse_counts_rising_edges_forward_with_b_at_0(void)
{
    avr_hal_encoder_attach(1u, 0x01u, no_hook);
    PCICR = 0u;
    PORTK &= (uint8_t)~0x01u; /* A driven by the test from here on, B undriven */
    DDRK |= 0x01u;
    GPIOR1 = PINK; /* the levels the vector starts from */
    for (uint8_t k = 0; k < 5u; k++) {
        PORTK |= 0x01u; /* A rises */
        pcint2();
        PORTK &= (uint8_t)~0x01u; /* A falls */
        pcint2();
    }
    TEST_ASSERT_EQUAL_HEX8(0x00u, PINK & 0x02u);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(5u, encoder_isr_state[0].fwd, "one raw-forward step per rising edge");
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(5u, encoder_isr_state[0].back, "falling edges raw-backward");
    TEST_ASSERT_EQUAL_UINT16(0u, encoder_isr_state[0].errors);
    TEST_ASSERT_EQUAL_UINT16(0u, encoder_isr_state[1].fwd + encoder_isr_state[1].back);
}

/* The first edge after attach on a Hall wheel is a rising one: counted forward, not backward. */
static void test_hall_first_rising_edge_is_forward(void)
{
    avr_hal_encoder_attach(1u, 0x01u, no_hook);
    PCICR = 0u;
    PORTK &= (uint8_t)~0x01u;
    DDRK |= 0x01u;
    GPIOR1 = PINK;
    PORTK |= 0x01u;
    pcint2();
    TEST_ASSERT_EQUAL_UINT16(1u, encoder_isr_state[0].fwd);
    TEST_ASSERT_EQUAL_UINT16(0u, encoder_isr_state[0].back);
}

int main(void)
{
    UNITY_BEGIN();
    /* simavr holds an undriven input at its last level, like a floating line: the tests with B at
     * 0 (a B line tied to GND, docs/hil.md) run before any attach has pulled B up */
    RUN_TEST(test_hall_first_rising_edge_is_forward);
    RUN_TEST(test_hall_pulse_counts_rising_edges_forward_with_b_at_0);
    RUN_TEST(test_encoder_attach_hall_wheel_leaves_b_without_pull_up);
    RUN_TEST(test_encoder_attach_quadrature_wheels_pull_up_both_lines);
    return UNITY_END();
}
