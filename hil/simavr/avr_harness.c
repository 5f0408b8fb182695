/*
 * avr_harness: runs an AgNav AVR ELF under libsimavr at 16 MHz and bridges
 * its UART0 to stdout.
 *
 *   avr_harness [--mcu NAME] [--freq HZ] [--seconds S] [--timestamps] FIRMWARE.elf
 *
 * Default output is the raw UART0 byte stream (unit-test text, MAVLink).
 * --timestamps prints one line per byte instead: "<simulated us> <hex byte>",
 * so tests can check timing in simulated time.
 * The run ends when the firmware sleeps with interrupts disabled (what the
 * unit-test runner does after UNITY_END), crashes, or --seconds of simulated
 * time pass. Exit codes: 0 done, 3 crashed, 4 time limit, 2 usage/load error.
 */
#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_irq.h>

#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <fcntl.h>
#include <unistd.h>

static avr_t *g_avr;
static int g_timestamps;

static void on_uart_byte(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    if (g_timestamps) {
        uint64_t t_us = g_avr->cycle * 1000000ull / g_avr->frequency;
        printf("%" PRIu64 " %02x\n", t_us, value & 0xffu);
    } else {
        putchar((int)(value & 0xffu));
    }
}

static int usage(void)
{
    fprintf(stderr, "usage: avr_harness [--mcu NAME] [--freq HZ] [--seconds S] [--timestamps] FIRMWARE.elf\n");
    return 2;
}

int main(int argc, char **argv)
{
    const char *mcu = "atmega2560";
    const char *elf = NULL;
    unsigned long freq = 16000000ul;
    double seconds = 60.0;

    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--mcu") && i + 1 < argc) {
            mcu = argv[++i];
        } else if (!strcmp(argv[i], "--freq") && i + 1 < argc) {
            freq = strtoul(argv[++i], NULL, 10);
        } else if (!strcmp(argv[i], "--seconds") && i + 1 < argc) {
            seconds = atof(argv[++i]);
        } else if (!strcmp(argv[i], "--timestamps")) {
            g_timestamps = 1;
        } else if (argv[i][0] == '-') {
            return usage();
        } else {
            elf = argv[i];
        }
    }
    if (elf == NULL || freq == 0 || seconds <= 0.0) {
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
    avr_load_firmware(g_avr, &fw);
    g_avr->frequency = freq;

    uint32_t flags = 0;
    avr_ioctl(g_avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~AVR_UART_FLAG_STDIO;
    avr_ioctl(g_avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            on_uart_byte, NULL);

    const uint64_t max_cycles = (uint64_t)(seconds * (double)freq);
    int state = cpu_Running;
    while (state != cpu_Done && state != cpu_Crashed) {
        state = avr_run(g_avr);
        if (g_avr->cycle >= max_cycles) {
            fflush(stdout);
            fprintf(stderr, "avr_harness: time limit of %.3f simulated s reached\n", seconds);
            return 4;
        }
    }
    fflush(stdout);
    return state == cpu_Crashed ? 3 : 0;
}
