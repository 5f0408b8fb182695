/*
 * avr_harness: runs an AgNav AVR ELF under libsimavr at 16 MHz and bridges
 * its UART0 to stdout.
 *
 *   avr_harness [--mcu NAME] [--freq HZ] [--seconds S] [--timestamps]
 *               [--enc-count N --enc-hz F] [--sonar-mm D] [--isr-stats] FIRMWARE.elf
 *
 * Default output is the raw UART0 byte stream (unit-test text, MAVLink).
 * --timestamps prints one line per byte instead: "<simulated us> <hex byte>",
 * so tests can check timing in simulated time.
 * The run ends when the firmware sleeps with interrupts disabled (what the
 * unit-test runner does after UNITY_END), crashes, or --seconds of simulated
 * time pass. Exit codes: 0 done, 3 crashed, 4 time limit, 2 usage/load error.
 *
 * Stimulus, on the pins of firmware/lib/hal/avr/board.h:
 *   --enc-count N --enc-hz F  N quadrature encoders on PORTK (A = PK2i, B = PK2i+1), each
 *                             stepping forward at F edges per second (phases staggered)
 *   --enc-mirror              encoders 1 and 3 step backward (the mirrored right wheels of a
 *                             differential drive: their raw quadrature runs B-leads-A)
 *   --enc-aligned             no stagger: all N encoders step at the same instant (one
 *                             interrupt sees every encoder change; worst case of a shared vector)
 *   --sonar-mm D              every sonar trigger (PA0..7, PC0..3) is answered on its echo
 *                             line (PB0..7, PD0..3) with a pulse of 2 D / 343 m/s after 200 us
 *   --uart-inject-hex H --uart-inject-hz F
 *                             the bytes H (hex) are fed to UART0's receiver F times per
 *                             second (e.g. a host HEARTBEAT + drive setpoint, so the
 *                             firmware sees a live link)
 *   --profile NAME:ADDR       cycles from entry of the function at byte address ADDR until
 *                             it returns (interrupts inside included); repeatable; stats to stderr
 *   --isr-stats               cycles spent in the encoder interrupt (PCINT2 vector entry to
 *                             return) are measured; min/mean/max go to stderr at the end
 *   --host-baud B             the host side of UART0 runs at B baud (its nominal rate), the
 *                             firmware at the rate its UBRR0/U2X0 give: every byte out (stdout) and
 *                             in (--uart-inject-hex) is re-read with the receiver's bit sampling
 *                             (avr_board_model.h); a byte the host loses is not printed. Default 0:
 *                             the host follows the firmware's rate (unit tests: unity_output.c's
 *                             setting is 117647 baud, no host rate is implied)
 *   --eeprom-write-us U       EEPROM programming time per byte (default 3296, Table 8-1; 0: simavr's
 *                             own, which completes a write at once)
 * At the end stderr gets "injected_edges=E0,E1,..." for the encoder check,
 * "uart_link host_baud=B to_host=N garbled=G framing=F to_avr=N garbled=G framing=F" with
 * --host-baud, and "eeprom_writes=N control_ticks=N control_gap_max_us=G" (the longest time
 * between two control ticks, avr_board_model.h).
 */
#include "avr_board_model.h"

#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/sim_interrupts.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_irq.h>

#include <inttypes.h>
#include <stdio.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <unistd.h>

static avr_t *g_avr;
static int g_timestamps;

#define MAX_ENC 4
#define MAX_SONAR 12
#define PCINT2_VECTOR_BYTE_ADDR (11u * 4u) /* ATmega2560: vector 11, 4 bytes per vector */
#define ECHO_DELAY_US 200u

static unsigned g_enc_count;
static int g_enc_aligned;
static int g_enc_mirror;
static double g_enc_hz;
static unsigned long g_enc_edges[MAX_ENC];
static unsigned g_enc_phase[MAX_ENC];
static avr_irq_t *g_enc_a[MAX_ENC], *g_enc_b[MAX_ENC];
static double g_sonar_mm = -1.0;
static avr_irq_t *g_echo[MAX_SONAR];
static int g_isr_stats;
static uint64_t g_sleep_cycles; /* cycles the core spent asleep (idle) */
static uint64_t g_sleep_calls;

#define MAX_PROF 16
typedef struct {
    char name[48];
    uint32_t addr;
    int depth_sp;     /* SP at entry (return address pushed), -1 when not inside */
    uint64_t start, n, sum, max, min;
} prof_t;
static prof_t g_prof[MAX_PROF];
static unsigned g_prof_n;
static uint8_t g_inject[512];
static unsigned g_inject_len;
static double g_inject_hz;
static avr_irq_t *g_uart_in;
static avr_model_link_t g_link;

static avr_cycle_count_t uart_inject(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)param;
    for (unsigned k = 0; k < g_inject_len; k++) {
        int v = avr_model_link_to_avr(&g_link, avr, g_inject[k]);
        if (v >= 0) {
            avr_raise_irq(g_uart_in, (uint32_t)v);
        }
    }
    return when + (avr_cycle_count_t)((double)avr->frequency / g_inject_hz);
}

static int parse_hex(const char *h)
{
    size_t n = strlen(h);
    if (n % 2u != 0u || n / 2u > sizeof g_inject) {
        return -1;
    }
    for (size_t k = 0; k < n / 2u; k++) {
        unsigned v;
        if (sscanf(h + 2u * k, "%2x", &v) != 1) {
            return -1;
        }
        g_inject[k] = (uint8_t)v;
    }
    g_inject_len = (unsigned)(n / 2u);
    return 0;
}

/* simavr's ATmega2560 model has no pin-change interrupt on PORTK (PCINT16..23), which the
 * real chip has and board.h uses for the encoders: the harness models it. Registers: PCICR
 * 0x68 (PCIE2 = bit 2), PCIFR 0x3B (PCIF2 = bit 2), PCMSK2 0x6D; vector 11. */
#define REG_PCICR 0x68
#define REG_PCIFR 0x3B
#define REG_PCMSK2 0x6D
static avr_int_vector_t g_pcint2 = {
    .enable = AVR_IO_REGBIT(REG_PCICR, 2),
    .raised = AVR_IO_REGBIT(REG_PCIFR, 2),
    .vector = 11,
};

/* Forward quadrature: phases 0..3 = AB 00, 10, 11, 01 (A leads B). */
static void enc_apply(unsigned i)
{
    static const uint8_t A[4] = {0, 1, 1, 0}, B[4] = {0, 0, 1, 1};
    unsigned ph = g_enc_phase[i];
    uint8_t before = (uint8_t)((g_enc_a[i]->value ? 1u : 0u) | (g_enc_b[i]->value ? 2u : 0u));
    avr_raise_irq(g_enc_a[i], A[ph]);
    avr_raise_irq(g_enc_b[i], B[ph]);
    uint8_t after = (uint8_t)(A[ph] | (B[ph] << 1));
    uint8_t changed = (uint8_t)((before ^ after) << (2u * i));
    if (changed & g_avr->data[REG_PCMSK2]) {
        avr_raise_interrupt(g_avr, &g_pcint2);
    }
}

static avr_cycle_count_t enc_tick(avr_t *avr, avr_cycle_count_t when, void *param)
{
    unsigned i = (unsigned)(uintptr_t)param;
    g_enc_phase[i] = (g_enc_phase[i] + ((g_enc_mirror && (i & 1u)) ? 3u : 1u)) & 3u;
    enc_apply(i);
    g_enc_edges[i]++;
    (void)avr;
    return when + (avr_cycle_count_t)((double)g_avr->frequency / g_enc_hz);
}

/* --enc-aligned: every encoder steps at once, then one pin-change interrupt. */
static avr_cycle_count_t enc_tick_all(avr_t *avr, avr_cycle_count_t when, void *param)
{
    static const uint8_t A[4] = {0, 1, 1, 0}, B[4] = {0, 0, 1, 1};
    (void)param;
    (void)avr;
    uint8_t changed = 0u;
    for (unsigned i = 0; i < g_enc_count; i++) {
        uint8_t before = (uint8_t)((g_enc_a[i]->value ? 1u : 0u) | (g_enc_b[i]->value ? 2u : 0u));
        g_enc_phase[i] = (g_enc_phase[i] + ((g_enc_mirror && (i & 1u)) ? 3u : 1u)) & 3u;
        unsigned ph = g_enc_phase[i];
        avr_raise_irq(g_enc_a[i], A[ph]);
        avr_raise_irq(g_enc_b[i], B[ph]);
        changed |= (uint8_t)((before ^ (uint8_t)(A[ph] | (B[ph] << 1))) << (2u * i));
        g_enc_edges[i]++;
    }
    if (changed & g_avr->data[REG_PCMSK2]) {
        avr_raise_interrupt(g_avr, &g_pcint2);
    }
    return when + (avr_cycle_count_t)((double)g_avr->frequency / g_enc_hz);
}

static avr_cycle_count_t echo_rise(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    (void)when;
    avr_raise_irq(g_echo[(uintptr_t)param], 1);
    return 0;
}

static avr_cycle_count_t echo_fall(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    (void)when;
    avr_raise_irq(g_echo[(uintptr_t)param], 0);
    return 0;
}

static void on_trigger(struct avr_irq_t *irq, uint32_t value, void *param)
{
    unsigned idx = (unsigned)(uintptr_t)param;
    if (value != 0 || irq->value == 0) {
        return; /* act on the falling edge of the trigger pulse */
    }
    uint64_t per_us = g_avr->frequency / 1000000u;
    uint64_t rise = ECHO_DELAY_US * per_us;
    uint64_t width = (uint64_t)(g_sonar_mm * 2000.0 / 343.0) * per_us;
    avr_cycle_timer_register(g_avr, rise, echo_rise, (void *)(uintptr_t)idx);
    avr_cycle_timer_register(g_avr, rise + width, echo_fall, (void *)(uintptr_t)idx);
}

static uint16_t sp_now(void) { return (uint16_t)(g_avr->data[0x5D] | (g_avr->data[0x5E] << 8)); }

static void on_uart_byte(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    int v = avr_model_link_to_host(&g_link, g_avr, (uint8_t)value);
    if (v < 0) {
        return; /* the host saw no frame */
    }
    if (g_timestamps) {
        uint64_t t_us = g_avr->cycle * 1000000ull / g_avr->frequency;
        printf("%" PRIu64 " %02x\n", t_us, (unsigned)v & 0xffu);
    } else {
        putchar(v & 0xff);
    }
}

static int usage(void)
{
    fprintf(stderr, "usage: avr_harness [--mcu NAME] [--freq HZ] [--seconds S] [--timestamps]\n"
                    "                   [--enc-count N --enc-hz F [--enc-mirror] [--enc-aligned]] [--sonar-mm D] [--isr-stats]\n"
                    "                   [--uart-inject-hex HEX --uart-inject-hz F] [--host-baud B] [--eeprom-write-us U]\n"
                    "                   FIRMWARE.elf\n");
    return 2;
}

int main(int argc, char **argv)
{
    const char *mcu = "atmega2560";
    const char *elf = NULL;
    unsigned long freq = 16000000ul;
    double seconds = 60.0;
    uint32_t eeprom_write_us = AVR_MODEL_EEPROM_WRITE_US;

    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--mcu") && i + 1 < argc) {
            mcu = argv[++i];
        } else if (!strcmp(argv[i], "--freq") && i + 1 < argc) {
            freq = strtoul(argv[++i], NULL, 10);
        } else if (!strcmp(argv[i], "--seconds") && i + 1 < argc) {
            seconds = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--timestamps")) {
            g_timestamps = 1;
        } else if (!strcmp(argv[i], "--enc-count") && i + 1 < argc) {
            g_enc_count = (unsigned)atoi(argv[++i]);
        } else if (!strcmp(argv[i], "--enc-hz") && i + 1 < argc) {
            g_enc_hz = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--sonar-mm") && i + 1 < argc) {
            g_sonar_mm = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--uart-inject-hex") && i + 1 < argc) {
            if (parse_hex(argv[++i]) != 0) {
                return usage();
            }
        } else if (!strcmp(argv[i], "--uart-inject-hz") && i + 1 < argc) {
            g_inject_hz = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--profile") && i + 1 < argc && g_prof_n < MAX_PROF) {
            const char *arg = argv[++i];
            const char *colon = strrchr(arg, ':');
            if (colon == NULL) {
                return usage();
            }
            prof_t *pf = &g_prof[g_prof_n++];
            snprintf(pf->name, sizeof pf->name, "%.*s", (int)(colon - arg), arg);
            pf->addr = (uint32_t)strtoul(colon + 1, NULL, 0);
            pf->depth_sp = -1;
            pf->min = UINT64_MAX;
        } else if (!strcmp(argv[i], "--enc-mirror")) {
            g_enc_mirror = 1;
        } else if (!strcmp(argv[i], "--enc-aligned")) {
            g_enc_aligned = 1;
        } else if (!strcmp(argv[i], "--isr-stats")) {
            g_isr_stats = 1;
        } else if (!strcmp(argv[i], "--host-baud") && i + 1 < argc) {
            g_link.host_baud = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (!strcmp(argv[i], "--eeprom-write-us") && i + 1 < argc) {
            eeprom_write_us = (uint32_t)strtoul(argv[++i], NULL, 10);
        } else if (argv[i][0] == '-') {
            return usage();
        } else {
            elf = argv[i];
        }
    }
    if (elf == NULL || freq == 0 || seconds <= 0.0 || g_enc_count > MAX_ENC || (g_enc_count > 0 && g_enc_hz <= 0.0)) {
        return usage();
    }

    elf_firmware_t fw;
    memset(&fw, 0, sizeof fw);
    /* libsimavr's ELF loader chats on stdout; keep stdout for UART bytes only. */
    fflush(stdout);
    int saved_stdout = dup(1);
    int devnull = open("/dev/null", O_WRONLY);
    dup2(devnull, 1);
    int rc = elf_read_firmware(elf, &fw);
    fflush(stdout);
    dup2(saved_stdout, 1);
    close(devnull);
    close(saved_stdout);
    if (rc != 0) {
        fprintf(stderr, "avr_harness: cannot read ELF '%s'\n", elf);
        return 2;
    }
    g_avr = avr_make_mcu_by_name(mcu);
    if (g_avr == NULL) {
        fprintf(stderr, "avr_harness: unknown MCU '%s'\n", mcu);
        return 2;
    }
    avr_init(g_avr);
    g_avr->log = 0;
    avr_model_fix(g_avr); /* simavr corrections shared with the SIL library (avr_board_model.h) */
    avr_model_eeprom_timing(g_avr, eeprom_write_us);
    avr_load_firmware(g_avr, &fw);
    g_avr->frequency = freq;

    uint32_t flags = 0;
    avr_ioctl(g_avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~AVR_UART_FLAG_STDIO;
    avr_ioctl(g_avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            on_uart_byte, NULL);

    if (g_enc_count > 0) {
        avr_register_vector(g_avr, &g_pcint2);
    }
    if (g_enc_count > 0) {
        /* The encoders drive their lines (push-pull): the firmware's PORTK pull-ups must not
         * lift them, which simavr does to an input pin unless it is declared external. */
        avr_ioport_external_t ext = {.name = 'K', .mask = (uint8_t)((1u << (2u * g_enc_count)) - 1u), .value = 0};
        avr_ioctl(g_avr, AVR_IOCTL_IOPORT_SET_EXTERNAL('K'), &ext);
    }
    for (unsigned i = 0; i < g_enc_count; i++) {
        g_enc_a[i] = avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ('K'), (int)(2u * i));
        g_enc_b[i] = avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ('K'), (int)(2u * i + 1u));
        enc_apply(i);
        /* start after boot (0.5 s), staggered so the encoders' edges interleave */
        avr_cycle_count_t start = freq / 2u + (g_enc_aligned ? 0u : (avr_cycle_count_t)((double)freq / g_enc_hz * i / g_enc_count));
        if (!g_enc_aligned) {
            avr_cycle_timer_register(g_avr, start, enc_tick, (void *)(uintptr_t)i);
        }
    }
    if (g_enc_aligned && g_enc_count > 0) {
        avr_cycle_timer_register(g_avr, freq / 2u, enc_tick_all, NULL);
    }
    if (g_inject_len > 0 && g_inject_hz > 0.0) {
        g_uart_in = avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
        avr_cycle_timer_register(g_avr, freq / 4u, uart_inject, NULL);
    }
    if (g_sonar_mm >= 0.0) {
        for (unsigned i = 0; i < MAX_SONAR; i++) {
            char trig_port = i < 8u ? 'A' : 'C', echo_port = i < 8u ? 'B' : 'D';
            unsigned pin = i < 8u ? i : i - 8u;
            avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ(trig_port), (int)pin),
                                    on_trigger, (void *)(uintptr_t)i);
            g_echo[i] = avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ(echo_port), (int)pin);
        }
    }

    avr_uart_t *uart0 = avr_model_uart0(g_avr);
    int baud_fixed = 0;
    const uint64_t max_cycles = (uint64_t)(seconds * (double)freq);
    int state = cpu_Running;
    int exit_rc = -1;
    uint64_t isr_n = 0, isr_sum = 0, isr_min = UINT64_MAX, isr_max = 0, isr_start = 0;
    uint16_t isr_sp = 0;
    int in_isr = 0;
    while (state != cpu_Done && state != cpu_Crashed) {
        uint64_t before = g_avr->cycle;
        state = avr_run(g_avr);
        if (!baud_fixed && (g_avr->data[0xC1] & 0x08u)) { /* TXEN0: the firmware set UBRR0 and U2X0 */
            avr_model_uart0_fix_baud(g_avr, uart0);
            baud_fixed = 1;
        }
        if (state == cpu_Sleeping) {
            g_sleep_cycles += g_avr->cycle - before;
            g_sleep_calls++;
        }
        if (g_isr_stats) {
            if (!in_isr && g_avr->pc == PCINT2_VECTOR_BYTE_ADDR) {
                in_isr = 1;
                isr_start = g_avr->cycle;
                isr_sp = sp_now();
            } else if (in_isr && sp_now() == (uint16_t)(isr_sp + 3u)) {
                uint64_t c = g_avr->cycle - isr_start;
                in_isr = 0;
                isr_n++;
                isr_sum += c;
                isr_min = c < isr_min ? c : isr_min;
                isr_max = c > isr_max ? c : isr_max;
            }
        }
        for (unsigned k = 0; k < g_prof_n; k++) {
            prof_t *pf = &g_prof[k];
            if (pf->depth_sp < 0) {
                if (g_avr->pc == pf->addr) {
                    pf->depth_sp = sp_now();
                    pf->start = g_avr->cycle;
                }
            } else if (sp_now() == (uint16_t)(pf->depth_sp + 3)) {
                uint64_t c = g_avr->cycle - pf->start;
                pf->depth_sp = -1;
                pf->n++;
                pf->sum += c;
                pf->max = c > pf->max ? c : pf->max;
                pf->min = c < pf->min ? c : pf->min;
            }
        }
        if (g_avr->cycle >= max_cycles) {
            fprintf(stderr, "avr_harness: time limit of %.3f simulated s reached\n", seconds);
            exit_rc = 4;
            break;
        }
    }
    fflush(stdout);
    if (g_enc_count > 0) {
        fprintf(stderr, "injected_edges=");
        for (unsigned i = 0; i < g_enc_count; i++) {
            fprintf(stderr, "%s%lu", i ? "," : "", g_enc_edges[i]);
        }
        fprintf(stderr, "\n");
    }
    if (g_link.host_baud != 0u) {
        fprintf(stderr, "uart_link host_baud=%u to_host=%u garbled=%u framing=%u to_avr=%u garbled=%u framing=%u\n",
                g_link.host_baud, g_link.to_host, g_link.to_host_garbled, g_link.to_host_framing, g_link.to_avr,
                g_link.to_avr_garbled, g_link.to_avr_framing);
    }
    fprintf(stderr, "eeprom_writes=%u control_ticks=%u control_gap_max_us=%u\n", avr_model_eeprom_writes(),
            avr_model_control_ticks(), avr_model_control_gap_max_us());
    fprintf(stderr, "sleep_fraction=%.3f sleep_steps=%llu\n", g_avr->cycle ? (double)g_sleep_cycles / (double)g_avr->cycle : 0.0,
            (unsigned long long)g_sleep_calls);
    if (g_isr_stats) {
        fprintf(stderr, "encoder_isr_cycles n=%llu min=%llu mean=%.1f max=%llu\n", (unsigned long long)isr_n,
                (unsigned long long)(isr_n ? isr_min : 0), isr_n ? (double)isr_sum / (double)isr_n : 0.0,
                (unsigned long long)isr_max);
    }
    for (unsigned k = 0; k < g_prof_n; k++) {
        const prof_t *pf = &g_prof[k];
        fprintf(stderr, "profile %s n=%llu min=%llu mean=%.1f max=%llu\n", pf->name, (unsigned long long)pf->n,
                (unsigned long long)(pf->n ? pf->min : 0), pf->n ? (double)pf->sum / (double)pf->n : 0.0,
                (unsigned long long)pf->max);
    }
    if (exit_rc >= 0) {
        return exit_rc;
    }
    return state == cpu_Crashed ? 3 : 0;
}
