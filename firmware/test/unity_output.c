/* Where Unity's characters go on each target, and how a test program ends. */
#include "unity_config.h"

#include <stdint.h>

#if defined(__AVR__)
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>

void agnav_test_output_start(void)
{
    UBRR0 = 16; /* 115200 baud at 16 MHz with U2X (simavr does not care) */
    UCSR0A = (uint8_t)(1u << U2X0);
    UCSR0B = (uint8_t)(1u << TXEN0);
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
}

void agnav_test_output_char(int c)
{
    while ((UCSR0A & (1u << UDRE0)) == 0u) {
    }
    UDR0 = (uint8_t)c;
}

void agnav_test_output_flush(void)
{
    while ((UCSR0A & (1u << TXC0)) == 0u && (UCSR0A & (1u << UDRE0)) == 0u) {
    }
}

void agnav_test_output_complete(void)
{
    /* Sleeping with interrupts off is how simavr knows the program is done. */
    cli();
    sleep_enable();
    sleep_cpu();
}

#elif defined(__arm__)

#define USART1_SR (*(volatile uint32_t *)0x40011000u)
#define USART1_DR (*(volatile uint32_t *)0x40011004u)
#define USART1_CR1 (*(volatile uint32_t *)0x4001100Cu)
#define RCC_APB2ENR (*(volatile uint32_t *)0x40023844u)

void agnav_test_output_start(void)
{
    RCC_APB2ENR |= (1u << 4);            /* USART1 clock */
    USART1_CR1 = (1u << 13) | (1u << 3); /* UE | TE */
}

void agnav_test_output_char(int c)
{
    while ((USART1_SR & (1u << 7)) == 0u) { /* TXE */
    }
    USART1_DR = (uint32_t)(c & 0xff);
}

void agnav_test_output_flush(void) {}

/* Semihosting SYS_EXIT: ends QEMU. Unity's own failure count is reported on
 * the console, so the exit is always "application exit". */
void agnav_test_output_complete(void)
{
    register uint32_t r0 __asm__("r0") = 0x18u;    /* SYS_EXIT */
    register uint32_t r1 __asm__("r1") = 0x20026u; /* ADP_Stopped_ApplicationExit */
    __asm__ volatile("bkpt 0xAB" : : "r"(r0), "r"(r1) : "memory");
    for (;;) {
    }
}

#else
#include <stdio.h>

void agnav_test_output_start(void) {}
void agnav_test_output_char(int c) { putchar(c); }
void agnav_test_output_flush(void) { fflush(stdout); }
void agnav_test_output_complete(void) {}
#endif
