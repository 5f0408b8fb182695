/*
 * Corrections that make simavr 1.6's ATmega2560 behave like the chip for AgNav's firmware,
 * shared by the unit-test/benchmark harness (avr_harness.c) and the lock-step SIL library
 * (avr_sil.c). Each one was found by a test that failed against the model, see avr_board_model.h.
 */
#include "avr_board_model.h"

#include <simavr/avr_extint.h>
#include <simavr/sim_interrupts.h>
#include <simavr/sim_io.h>

#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* ---- timer interrupt flag registers: write-one-to-clear, as on the chip ----------------------
 * simavr 1.6 clears EVERY pending flag of a TIFRn on any write to it: hal_idle_until()'s
 * "TIFR5 = 1 << OCF5A" then drops a Timer5 overflow that became pending under cli(), the
 * firmware's 32-bit clock loses 262 ms and the watchdog resets the board (seen at t = 1.31 s in
 * the wall_ahead scenario). The chip clears only the bits written as 1: each TIFRn write goes
 * through simavr's handler, then every flag that was set and written 0 is raised again. */
#define TIFR_FIRST 0x35 /* TIFR0 .. TIFR5 = 0x35 .. 0x3A */
#define TIFR_COUNT 6
static struct {
    avr_io_write_t c;
    void *param;
} g_tifr_orig[TIFR_COUNT];

static avr_int_vector_t *vector_for_flag(avr_t *avr, avr_io_addr_t addr, uint8_t bit)
{
    for (int v = 0; v < 64; v++) {
        avr_int_vector_t *iv = avr->interrupts.vector[v];
        if (iv != NULL && iv->raised.reg == addr && iv->raised.bit == bit && iv->raised.mask == 1u) {
            return iv;
        }
    }
    return NULL;
}

static void tifr_write(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    unsigned k = (unsigned)(uintptr_t)param;
    uint8_t before = avr->data[addr];
    if (g_tifr_orig[k].c != NULL) {
        g_tifr_orig[k].c(avr, addr, v, g_tifr_orig[k].param);
    } else {
        avr->data[addr] = (uint8_t)(before & ~v);
    }
    uint8_t lost = (uint8_t)(before & (uint8_t)~v & (uint8_t)~avr->data[addr]);
    for (uint8_t b = 0; lost != 0u && b < 8u; b++) {
        if (lost & (1u << b)) {
            avr_int_vector_t *iv = vector_for_flag(avr, addr, b);
            if (iv != NULL) {
                avr_raise_interrupt(avr, iv);
            } else {
                avr->data[addr] |= (uint8_t)(1u << b);
            }
        }
    }
}

void avr_model_hook_tifr(avr_t *avr)
{
    for (unsigned k = 0; k < TIFR_COUNT; k++) {
        unsigned a = AVR_DATA_TO_IO(TIFR_FIRST + k);
        if (avr->io[a].w.c == tifr_write) {
            continue;
        }
        g_tifr_orig[k].c = avr->io[a].w.c;
        g_tifr_orig[k].param = avr->io[a].w.param;
        avr->io[a].w.c = tifr_write;
        avr->io[a].w.param = (void *)(uintptr_t)k;
    }
}

void avr_model_no_level_poll(avr_t *avr)
{
    if (getenv("AGNAV_AVR_SIL_LEVEL_POLL") != NULL) {
        return; /* keep simavr's default (benchmark of its cost only) */
    }
    /* INTn pins in low-level mode (reset state; INT4/INT5 = PE4/PE5 carry the servo PWM, INT0..3
     * the echoes 8..11 before EICRA is set) make simavr poll the pin with an avr_ioctl() every
     * cycle while it is low: up to 5x slower. The firmware never uses level mode: turned off. */
    for (uint8_t i = 0; i < 8u; i++) {
        avr_extint_set_strict_lvl_trig(avr, i, 0);
    }
}


avr_uart_t *avr_model_uart0(avr_t *avr)
{
    for (avr_io_t *io = avr->io_port; io != NULL; io = io->next) {
        if (io->kind != NULL && strcmp(io->kind, "uart") == 0 && ((avr_uart_t *)io)->name == '0') {
            return (avr_uart_t *)io;
        }
    }
    return NULL;
}


/* simavr computes the byte time when UBRR0 is written; hal_uart_init() writes UBRR0 before
 * U2X0, so simavr would run the UART at half speed (and counts a parity bit that 8N1 does
 * not have). Byte time of the real USART: 10 bits x (UBRR0 + 1) x (U2X0 ? 8 : 16) cycles. */
void avr_model_uart0_fix_baud(avr_t *avr, avr_uart_t *uart0)
{
    if (uart0 == NULL || avr == NULL) {
        return;
    }
    uint32_t ubrr = (uint32_t)(avr->data[0xC4] | ((avr->data[0xC5] & 0x0Fu) << 8)); /* UBRR0L/H */
    uint32_t u2x = avr->data[0xC0] & 0x02u;                                          /* UCSR0A U2X0 */
    uart0->cycles_per_byte = 10u * (ubrr + 1u) * (u2x ? 8u : 16u);
}

/* simavr's raw mode usleep()s through a sleeping core to stay in wall-clock time. */
static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr;
    (void)how_long;
}

void avr_model_fix(avr_t *avr)
{
    avr->sleep = no_sleep;
    avr_model_no_level_poll(avr);
    avr_model_hook_tifr(avr);
}
