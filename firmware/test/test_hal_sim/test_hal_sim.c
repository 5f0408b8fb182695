/* The simulated HAL is what every other native test and the SIL stand on. */
#include <unity.h>

#include "hal.h"
#include "hal_clock_ms.h"
#include "sim/hal_sim.h"

static uint8_t s_last_idx, s_last_ab, s_calls;
static uint32_t s_last_t;

static void on_edge(uint8_t idx, uint8_t ab, uint32_t t_us)
{
    s_last_idx = idx;
    s_last_ab = ab;
    s_last_t = t_us;
    s_calls++;
}

void setUp(void)
{
    sim_reset();
    s_calls = 0;
}

void tearDown(void) {}

static void test_sim_time_advances_and_wraps_at_32_bits(void)
{
    sim_time_set_us(0xFFFFFF00u);
    TEST_ASSERT_EQUAL_UINT32(4294967u, hal_time_ms());
    sim_time_advance_us(5000u);
    TEST_ASSERT_EQUAL_UINT32(0x1288u, hal_time_us()); /* microseconds wrap ... */
    TEST_ASSERT_EQUAL_UINT32(4294972u, hal_time_ms()); /* ... milliseconds count on */
}

/* The millisecond clock the AVR and sim HALs share: against a 64-bit reference, across the microsecond
 * clock's wrap, with short steps (the 16-bit path) and long gaps (the division). */
static void test_clock_ms_counts_on_across_the_microsecond_wrap(void)
{
    hal_clock_ms_t c;
    uint32_t start_us = 0xFFFFFFFFu - 3000000u; /* 3 s before the wrap */
    hal_clock_ms_start(&c, start_us);
    uint64_t t = start_us; /* true microseconds, never wrapping */
    uint32_t steps[] = {1u, 999u, 1000u, 1001u, 4321u, 65535u, 65536u, 70000u, 250000u, 1234567u};
    for (uint32_t i = 0; i < 2000u; i++) {
        t += steps[i % (sizeof steps / sizeof steps[0])];
        uint32_t ms = hal_clock_ms_update(&c, (uint32_t)t);
        TEST_ASSERT_EQUAL_UINT32((uint32_t)(t / 1000u), ms);
    }
    TEST_ASSERT_TRUE(t > 0x100000000ull + 100000000ull); /* well past the wrap */
}

static void test_sim_uart_round_trip_keeps_byte_order(void)
{
    const uint8_t out[3] = {0xFD, 0x01, 0x02};
    uint8_t got[4] = {0};
    TEST_ASSERT_EQUAL_UINT16(3u, hal_uart_write(HAL_UART_LINK, out, 3u));
    TEST_ASSERT_EQUAL_UINT16(3u, sim_uart_take_tx(HAL_UART_LINK, got, 4u));
    TEST_ASSERT_EQUAL_UINT8_ARRAY(out, got, 3);
    TEST_ASSERT_EQUAL_UINT16(3u, sim_uart_put_rx(HAL_UART_LINK, out, 3u));
    TEST_ASSERT_EQUAL_UINT16(3u, hal_uart_read(HAL_UART_LINK, got, 4u));
    TEST_ASSERT_EQUAL_UINT8_ARRAY(out, got, 3);
    TEST_ASSERT_EQUAL_UINT16(0u, hal_uart_read(HAL_UART_LINK, got, 4u));
}

static void test_sim_eeprom_starts_erased_and_keeps_writes(void)
{
    uint8_t b[2];
    hal_eeprom_read(10u, b, 2u);
    TEST_ASSERT_EQUAL_HEX8(0xFF, b[0]);
    const uint8_t w[2] = {0x12, 0x34};
    TEST_ASSERT_TRUE(hal_eeprom_write_byte(10u, w[0]));
    TEST_ASSERT_TRUE(hal_eeprom_write_byte(11u, w[1]));
    hal_eeprom_read(10u, b, 2u);
    TEST_ASSERT_EQUAL_UINT8_ARRAY(w, b, 2);
    TEST_ASSERT_EQUAL_HEX8(0x34, sim_eeprom_bytes()[11]);
    TEST_ASSERT_FALSE_MESSAGE(hal_eeprom_write_byte((uint16_t)SIM_EEPROM_SIZE, 1u), "beyond the size");
}

static void test_sim_eeprom_is_busy_for_the_set_programming_time(void)
{
    TEST_ASSERT_FALSE(hal_eeprom_busy());
    sim_eeprom_set_write_us(3300u);
    sim_time_set_us(1000u);
    TEST_ASSERT_TRUE(hal_eeprom_write_byte(5u, 0x5Au));
    TEST_ASSERT_TRUE(hal_eeprom_busy());
    sim_time_set_us(1000u + 3299u);
    TEST_ASSERT_TRUE(hal_eeprom_busy());
    sim_time_set_us(1000u + 3300u);
    TEST_ASSERT_FALSE(hal_eeprom_busy());
    TEST_ASSERT_EQUAL_UINT32(1u, sim_eeprom_writes());
}

static void test_sim_encoder_edge_reaches_hook_with_time(void)
{
    hal_encoder_attach(2u, 0u, on_edge);
    sim_time_set_us(1234u);
    sim_encoder_edge(1u, 2u);
    TEST_ASSERT_EQUAL_UINT8(1u, s_calls);
    TEST_ASSERT_EQUAL_UINT8(1u, s_last_idx);
    TEST_ASSERT_EQUAL_UINT8(2u, s_last_ab);
    TEST_ASSERT_EQUAL_UINT32(1234u, s_last_t);
    sim_encoder_edge(3u, 1u); /* not attached: ignored */
    TEST_ASSERT_EQUAL_UINT8(1u, s_calls);
}

/* hal.h: a Hall wheel's B reads 0, whatever the world sets its B line to; quadrature wheels see both. */
static void test_sim_encoder_hall_wheel_hook_sees_b_as_0(void)
{
    hal_encoder_attach(2u, 0x01u, on_edge); /* wheel 0 Hall, wheel 1 quadrature */
    sim_encoder_edge(0u, 3u);
    TEST_ASSERT_EQUAL_UINT8(0u, s_last_idx);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(2u, s_last_ab, "A high, B masked");
    sim_encoder_edge(0u, 1u);
    TEST_ASSERT_EQUAL_HEX8(0u, s_last_ab);
    sim_encoder_edge(1u, 3u);
    TEST_ASSERT_EQUAL_UINT8(1u, s_last_idx);
    TEST_ASSERT_EQUAL_HEX8(3u, s_last_ab);
    TEST_ASSERT_TRUE(hal_clock_from_crystal());
}

static void test_sim_irq_save_restore_nests(void)
{
    hal_irq_state_t outer = hal_irq_save();
    hal_irq_state_t inner = hal_irq_save();
    hal_irq_restore(inner);
    TEST_ASSERT_TRUE(sim_irq_masked());
    hal_irq_restore(outer);
    TEST_ASSERT_FALSE(sim_irq_masked());
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_sim_time_advances_and_wraps_at_32_bits);
    RUN_TEST(test_clock_ms_counts_on_across_the_microsecond_wrap);
    RUN_TEST(test_sim_uart_round_trip_keeps_byte_order);
    RUN_TEST(test_sim_eeprom_starts_erased_and_keeps_writes);
    RUN_TEST(test_sim_eeprom_is_busy_for_the_set_programming_time);
    RUN_TEST(test_sim_encoder_edge_reaches_hook_with_time);
    RUN_TEST(test_sim_encoder_hall_wheel_hook_sees_b_as_0);
    RUN_TEST(test_sim_irq_save_restore_nests);
    return UNITY_END();
}
