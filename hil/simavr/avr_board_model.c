/*
 * Corrections that make simavr 1.6's ATmega2560 behave like the chip for AgNav's firmware, and the
 * link UART's bit timing, EEPROM programming time and control-period watch, shared by the
 * unit-test/benchmark harness (avr_harness.c) and the lock-step SIL library (avr_sil.c). Each
 * correction was found by a test that failed against the model; the models are described in
 * avr_board_model.h.
 */
#include "avr_board_model.h"

#include <simavr/avr_extint.h>
#include <simavr/sim_cycle_timers.h>
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
    avr_model_eeprom_timing(avr, AVR_MODEL_EEPROM_WRITE_US);
    avr_model_watch_control(avr);
}

/* ---- link UART bit timing (avr_board_model.h) ---------------------------------------------- */
#define REG_UCSR0A 0xC0
#define REG_UBRR0L 0xC4
#define REG_UBRR0H 0xC5
#define U2X0_BIT 0x02u

/* Line level at time t after the start edge of an 8N1 frame of `byte` with bit time tx_bit. */
static int line_level(uint8_t byte, double t, double tx_bit)
{
    if (t < 0.0) {
        return 1; /* idle */
    }
    long k = (long)(t / tx_bit);
    if (k == 0) {
        return 0; /* start bit */
    }
    if (k <= 8) {
        return (byte >> (k - 1)) & 1; /* data, LSB first */
    }
    return k == 9 ? 1 : 0; /* stop bit, then the next frame's start bit */
}

int avr_model_uart_resample(uint8_t byte, double tx_bit, double rx_bit, unsigned samples)
{
    double ts = rx_bit / (double)samples;
    double lag = tx_bit < rx_bit ? ts : 0.0; /* start edge seen up to one sample tick late */
    unsigned first = samples / 2u;           /* first voting sample: 8 of 16, 4 of 8 */
    int bits[10];
    for (unsigned k = 0; k < 10u; k++) {
        int ones = 0;
        for (unsigned j = 0; j < 3u; j++) {
            unsigned n = k * samples + first + j; /* sample number in the frame, 1 = the edge tick */
            ones += line_level(byte, lag + (double)(n - 1u) * ts, tx_bit);
        }
        bits[k] = ones >= 2;
    }
    if (bits[0]) {
        return -1; /* start bit read high: taken as a spike, no frame */
    }
    int out = 0;
    for (unsigned k = 1; k <= 8u; k++) {
        out |= bits[k] << (k - 1u);
    }
    return bits[9] ? out : (out | 0x100);
}

double avr_model_uart0_bit_cycles(const avr_t *avr, unsigned *samples)
{
    unsigned ubrr = (unsigned)(avr->data[REG_UBRR0L] | ((avr->data[REG_UBRR0H] & 0x0Fu) << 8));
    unsigned s = (avr->data[REG_UCSR0A] & U2X0_BIT) ? 8u : 16u;
    if (samples != NULL) {
        *samples = s;
    }
    return (double)(ubrr + 1u) * (double)s;
}

int avr_model_link_to_host(avr_model_link_t *l, const avr_t *avr, uint8_t byte)
{
    l->to_host++;
    if (l->host_baud == 0u) {
        return byte;
    }
    double fw_bit = avr_model_uart0_bit_cycles(avr, NULL);
    int got = avr_model_uart_resample(byte, fw_bit, (double)avr->frequency / (double)l->host_baud, 16u);
    if (got != (int)byte) {
        l->to_host_garbled++;
        l->to_host_framing += got >= 0 && (got & 0x100) ? 1u : 0u;
    }
    return got;
}

int avr_model_link_to_avr(avr_model_link_t *l, const avr_t *avr, uint8_t byte)
{
    l->to_avr++;
    if (l->host_baud == 0u) {
        return byte;
    }
    unsigned samples;
    double fw_bit = avr_model_uart0_bit_cycles(avr, &samples);
    int got = avr_model_uart_resample(byte, (double)avr->frequency / (double)l->host_baud, fw_bit, samples);
    if (got != (int)byte) {
        l->to_avr_garbled++;
        if (got >= 0 && (got & 0x100)) {
            l->to_avr_framing++;
            got = (got & 0xFF) | UART_INPUT_FE;
        }
    }
    return got;
}

/* ---- EEPROM programming time (avr_board_model.h) ------------------------------------------- */
#define REG_EECR 0x3F
#define EERE_BIT 0x01u
#define EEPE_BIT 0x02u
#define EEMPE_BIT 0x04u
static struct {
    avr_io_write_t c;
    void *param;
    avr_t *avr;
    uint32_t write_us;   /* programming time */
    uint64_t busy_until; /* cycle EEPE falls; 0 idle */
    uint32_t writes, refused;
} g_ee;

static avr_cycle_count_t ee_done(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)when;
    (void)param;
    avr->data[REG_EECR] &= (uint8_t)~EEPE_BIT;
    g_ee.busy_until = 0u;
    return 0;
}

static void eecr_write(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    (void)param;
    if (g_ee.busy_until > avr->cycle) {
        if (v & (EEPE_BIT | EERE_BIT)) {
            g_ee.refused++;
        }
        v = (uint8_t)(v & ~(EEPE_BIT | EERE_BIT));
        if (g_ee.c != NULL) {
            g_ee.c(avr, addr, v, g_ee.param);
        } else {
            avr->data[addr] = v;
        }
        avr->data[addr] |= EEPE_BIT;
        return;
    }
    int program = (avr->data[addr] & EEMPE_BIT) && (v & EEPE_BIT);
    if (g_ee.c != NULL) {
        g_ee.c(avr, addr, v, g_ee.param);
    } else {
        avr->data[addr] = v;
    }
    if (program) {
        g_ee.writes++;
    }
    if (program && g_ee.write_us > 0u) {
        avr_cycle_count_t cycles = (avr_cycle_count_t)g_ee.write_us * avr->frequency / 1000000u;
        g_ee.busy_until = avr->cycle + cycles;
        avr->data[addr] |= EEPE_BIT;
        avr_cycle_timer_register(avr, cycles, ee_done, NULL);
    }
}

void avr_model_eeprom_timing(avr_t *avr, uint32_t write_us)
{
    unsigned a = AVR_DATA_TO_IO(REG_EECR);
    if (avr->io[a].w.c != eecr_write) {
        g_ee.c = avr->io[a].w.c;
        g_ee.param = avr->io[a].w.param;
        avr->io[a].w.c = eecr_write;
        avr->io[a].w.param = NULL;
    }
    if (g_ee.avr != avr) {
        g_ee.avr = avr;
        g_ee.busy_until = 0u;
        g_ee.writes = g_ee.refused = 0u;
    }
    g_ee.write_us = write_us;
}

void avr_model_eeprom_after_reset(avr_t *avr)
{
    if (g_ee.avr == avr && g_ee.busy_until > avr->cycle) {
        avr->data[REG_EECR] |= EEPE_BIT;
        avr_cycle_timer_cancel(avr, ee_done, NULL);
        avr_cycle_timer_register(avr, g_ee.busy_until - avr->cycle, ee_done, NULL);
    }
}

uint32_t avr_model_eeprom_writes(void) { return g_ee.writes; }
uint32_t avr_model_eeprom_refused(void) { return g_ee.refused; }

/* ---- control period (avr_board_model.h) ---------------------------------------------------- */
#define REG_OCR3BL 0x9A
#define REG_OCR4AL 0xA8
#define TICK_MERGE_US 1000u
static struct {
    avr_io_write_t c[2];
    void *param[2];
    avr_t *avr;
    uint64_t last_cycle;
    uint32_t ticks, gap_max_us;
} g_ctl;

static void ctl_write(struct avr_t *avr, avr_io_addr_t addr, uint8_t v, void *param)
{
    unsigned k = (unsigned)(uintptr_t)param;
    if (g_ctl.c[k] != NULL) {
        g_ctl.c[k](avr, addr, v, g_ctl.param[k]);
    } else {
        avr->data[addr] = v;
    }
    uint64_t per_us = avr->frequency / 1000000u;
    if (g_ctl.ticks != 0u) {
        uint64_t gap_us = (avr->cycle - g_ctl.last_cycle) / per_us;
        if (gap_us < TICK_MERGE_US) {
            return; /* the same tick */
        }
        if (gap_us > g_ctl.gap_max_us) {
            g_ctl.gap_max_us = (uint32_t)gap_us;
        }
    }
    g_ctl.last_cycle = avr->cycle;
    g_ctl.ticks++;
}

void avr_model_watch_control(avr_t *avr)
{
    static const uint16_t REG[2] = {REG_OCR3BL, REG_OCR4AL};
    if (g_ctl.avr != avr) {
        memset(&g_ctl, 0, sizeof g_ctl);
        g_ctl.avr = avr;
    }
    for (unsigned k = 0; k < 2u; k++) {
        unsigned a = AVR_DATA_TO_IO(REG[k]);
        if (avr->io[a].w.c == ctl_write) {
            continue;
        }
        g_ctl.c[k] = avr->io[a].w.c;
        g_ctl.param[k] = avr->io[a].w.param;
        avr->io[a].w.c = ctl_write;
        avr->io[a].w.param = (void *)(uintptr_t)k;
    }
}

uint32_t avr_model_control_ticks(void) { return g_ctl.ticks; }

uint32_t avr_model_control_gap_max_us(void)
{
    uint32_t g = g_ctl.gap_max_us;
    g_ctl.gap_max_us = 0u;
    return g;
}
