/*
 * The ATmega2560 EEPROM of the AVR HAL backend under simavr (megaatmega2560 env only), whose board model
 * holds EECR.EEPE for 3.3 ms per programmed byte (avr_harness --eeprom-write-us, datasheet Table 8-1):
 * hal_eeprom_write_byte() starts the write and returns without waiting, hal_eeprom_busy() follows EEPE,
 * and the byte reads back once the EEPROM is free.
 */
#include "../hal_avr_under_test.h"

#include <avr/interrupt.h>
#include <unity.h>

void setUp(void) {}
void tearDown(void) {}

static void test_a_byte_write_returns_at_once_and_busy_follows_eepe(void)
{
    while (avr_hal_eeprom_busy()) {
    }
    uint8_t old;
    avr_hal_eeprom_read(100u, &old, 1u);
    uint8_t v = (uint8_t)(old ^ 0x5Au);
    uint32_t t0 = avr_hal_time_us();
    TEST_ASSERT_TRUE(avr_hal_eeprom_write_byte(100u, v));
    uint32_t call_us = avr_hal_time_us() - t0;
    TEST_ASSERT_TRUE_MESSAGE(call_us < 100u, "the write waited for the programming");
    TEST_ASSERT_TRUE_MESSAGE(avr_hal_eeprom_busy(), "EEPE is set while the byte programs");
    TEST_ASSERT_TRUE((EECR & _BV(EEPE)) != 0u);
    while (avr_hal_eeprom_busy()) {
    }
    uint32_t took_us = avr_hal_time_us() - t0;
    TEST_ASSERT_TRUE_MESSAGE(took_us >= 3000u && took_us <= 4000u, "3.3 ms of programming");
    uint8_t back;
    avr_hal_eeprom_read(100u, &back, 1u);
    TEST_ASSERT_EQUAL_HEX8(v, back);
}

static void test_a_byte_beyond_the_eeprom_is_refused(void)
{
    TEST_ASSERT_FALSE(avr_hal_eeprom_write_byte((uint16_t)(E2END + 1u), 1u));
    TEST_ASSERT_FALSE(avr_hal_eeprom_busy());
    TEST_ASSERT_EQUAL_UINT16(4096u, avr_hal_eeprom_size());
}

int main(void)
{
    avr_hal_init();
    sei(); /* Timer5's overflow extends hal_time_us */
    UNITY_BEGIN();
    RUN_TEST(test_a_byte_write_returns_at_once_and_busy_follows_eepe);
    RUN_TEST(test_a_byte_beyond_the_eeprom_is_refused);
    return UNITY_END();
}
