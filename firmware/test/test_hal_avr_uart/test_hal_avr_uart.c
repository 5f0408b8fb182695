/*
 * The ATmega2560 link UART's bit rate, from the registers hal_uart_init() writes (env
 * megaatmega2560 only, under simavr: the other envs list this suite in test_ignore).
 * Unit-test builds link the sim backend as "the HAL", so the AVR backend is compiled into this
 * file under other names (avr_hal_*), as test_hal_stm32 does for the STM32.
 *
 * Actual rate (ATmega2560 datasheet 2549Q, 22.3.1, Table 22-1): F_CPU / (16 (UBRR0 + 1)) with
 * U2X0 = 0, F_CPU / (8 (UBRR0 + 1)) with U2X0 = 1. The link's budget is 1 % of the nominal rate
 * (BENCHMARKS.md); each supported rate must also be the best setting the clock allows (searched
 * over every UBRR0 and U2X0 here), with normal speed on a tie (16 samples a bit, 22.8.3).
 * USART0 also carries this program's Unity output: every call is followed by
 * agnav_test_output_start(), which puts the output setting back.
 */
#include "../hal_avr_under_test.h"

#include <stdio.h>
#include <unity.h>

#include "unity_config.h"

/* The rates the AVR link supports at 16 MHz (docs/serial.md), and the one it refuses. */
static const uint32_t SUPPORTED_BAUD[] = {9600u, 19200u, 38400u, 57600u};
#define REFUSED_BAUD 115200u
#define ERROR_BUDGET_PPM 10000u /* 1 % */

typedef struct {
    uint16_t ubrr;
    uint8_t ucsra, ucsrb, ucsrc;
} uart_regs_t;

typedef struct {
    uint16_t ubrr;
    uint8_t u2x;
    uint32_t err_ppm;
} uart_setting_t;

/* |actual - baud| / baud in parts per million, actual = F_CPU / (samples (ubrr + 1)). */
static uint32_t rate_error_ppm(uint32_t baud, uint16_t ubrr, uint8_t u2x)
{
    uint64_t clocks = (uint64_t)(u2x ? 8u : 16u) * (ubrr + 1u) * baud; /* F_CPU x baud / actual */
    uint64_t off = clocks > F_CPU ? clocks - F_CPU : F_CPU - clocks;
    if (off > clocks / 8u) {
        return 125000u + 1u; /* beyond 12.5 %: no candidate, and spares a 64-bit division */
    }
    return (uint32_t)(off * 1000000u / clocks);
}

/* The smallest-error setting over all of UBRR0 (12 bits) and U2X0; normal speed wins a tie. */
static uart_setting_t best_setting(uint32_t baud)
{
    uart_setting_t best = {0u, 0u, UINT32_MAX};
    for (uint8_t u2x = 0u; u2x < 2u; u2x++) {
        for (uint16_t ubrr = 0u; ubrr < 4096u; ubrr++) {
            uint32_t e = rate_error_ppm(baud, ubrr, u2x);
            if (e < best.err_ppm) {
                best.ubrr = ubrr;
                best.u2x = u2x;
                best.err_ppm = e;
            }
        }
    }
    return best;
}

/* hal_uart_init(baud) on a USART0 set to a sentinel, and what it left in the registers. The
 * transmitter stays on: simavr 1.6 clears UDRE0 when TXEN0 goes off and never sets it again. */
#define SENTINEL_UBRR 0x0FFFu
#define SENTINEL_UCSRB (1u << TXEN0)
static uart_regs_t init_and_read(uint8_t port, uint32_t baud)
{
    agnav_test_output_flush();
    UCSR0B = SENTINEL_UCSRB;
    UCSR0A = 0u;
    UCSR0C = 0u;
    UBRR0 = SENTINEL_UBRR;
    avr_hal_uart_init(port, baud);
    uart_regs_t r = {UBRR0, UCSR0A, UCSR0B, UCSR0C};
    agnav_test_output_start();
    return r;
}

void setUp(void) {}
void tearDown(void) {}

static void check_supported(uint32_t baud)
{
    uart_regs_t r = init_and_read(HAL_UART_LINK, baud);
    uint8_t u2x = (uint8_t)((r.ucsra >> U2X0) & 1u);
    uint32_t err = rate_error_ppm(baud, r.ubrr, u2x);
    uart_setting_t best = best_setting(baud);
    char msg[80];
    snprintf(msg, sizeof msg, "%lu baud: UBRR0 %u U2X0 %u, error %lu ppm", (unsigned long)baud, r.ubrr, u2x,
             (unsigned long)err);
    TEST_ASSERT_TRUE_MESSAGE(err <= ERROR_BUDGET_PPM, msg);
    TEST_ASSERT_EQUAL_UINT16_MESSAGE(best.ubrr, r.ubrr, msg);
    TEST_ASSERT_EQUAL_UINT8_MESSAGE(best.u2x, u2x, msg);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE((1u << RXEN0) | (1u << TXEN0) | (1u << RXCIE0), r.ucsrb, msg);
    TEST_ASSERT_EQUAL_HEX8_MESSAGE((1u << UCSZ01) | (1u << UCSZ00), r.ucsrc, msg); /* 8N1 */
}

static void test_hal_uart_init_9600_baud_is_the_best_setting_within_1_percent(void) { check_supported(SUPPORTED_BAUD[0]); }
static void test_hal_uart_init_19200_baud_is_the_best_setting_within_1_percent(void) { check_supported(SUPPORTED_BAUD[1]); }
static void test_hal_uart_init_38400_baud_is_the_best_setting_within_1_percent(void) { check_supported(SUPPORTED_BAUD[2]); }
static void test_hal_uart_init_57600_baud_is_the_best_setting_within_1_percent(void) { check_supported(SUPPORTED_BAUD[3]); }

/* 16 MHz has no setting within 1 % of 115200: the nearest are F_CPU / (8 x 17) = 117647 baud
 * (+2.12 %) and F_CPU / (16 x 9) = 111111 baud (-3.55 %). hal_uart_init refuses it and leaves
 * USART0 as it was. */
static void test_hal_uart_init_refuses_115200_baud_that_16_mhz_cannot_meet(void)
{
    uart_setting_t best = best_setting(REFUSED_BAUD);
    TEST_ASSERT_UINT32_WITHIN_MESSAGE(100u, 21200u, best.err_ppm, "best 115200 setting at 16 MHz: +2.12 %");
    TEST_ASSERT_TRUE_MESSAGE(best.err_ppm > ERROR_BUDGET_PPM, "a 115200 setting within 1 % exists");
    uart_regs_t r = init_and_read(HAL_UART_LINK, REFUSED_BAUD);
    TEST_ASSERT_EQUAL_HEX16_MESSAGE(SENTINEL_UBRR, r.ubrr, "UBRR0 written for a refused rate");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(SENTINEL_UCSRB, r.ucsrb, "USART0 receiver or interrupt enabled at a refused rate");
    TEST_ASSERT_EQUAL_HEX8_MESSAGE(0u, r.ucsrc, "frame format written for a refused rate");
}

static void test_hal_uart_init_ignores_ports_other_than_the_link(void)
{
    uart_regs_t r = init_and_read(HAL_UART_DEBUG, 57600u);
    TEST_ASSERT_EQUAL_HEX16(SENTINEL_UBRR, r.ubrr);
    TEST_ASSERT_EQUAL_HEX8(SENTINEL_UCSRB, r.ucsrb);
}

int main(void)
{
    UNITY_BEGIN();
    RUN_TEST(test_hal_uart_init_9600_baud_is_the_best_setting_within_1_percent);
    RUN_TEST(test_hal_uart_init_19200_baud_is_the_best_setting_within_1_percent);
    RUN_TEST(test_hal_uart_init_38400_baud_is_the_best_setting_within_1_percent);
    RUN_TEST(test_hal_uart_init_57600_baud_is_the_best_setting_within_1_percent);
    RUN_TEST(test_hal_uart_init_refuses_115200_baud_that_16_mhz_cannot_meet);
    RUN_TEST(test_hal_uart_init_ignores_ports_other_than_the_link);
    return UNITY_END();
}
