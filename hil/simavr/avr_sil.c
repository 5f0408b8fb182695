/*
 * AgNav AVR software-in-the-loop: the C API of hil/sil/sil_api.h (same names, same
 * semantics, so agnav_host.sil.binding loads either library) backed by libsimavr running
 * the REAL ATmega2560 firmware ELF (PlatformIO env megaatmega2560) at 16 MHz.
 * Built into build/sil/libagnav_avr_sil.so by agnav_host.sil.avr_build.
 *
 * ELF: sil_avr_set_elf(path) before sil_init() (the Python binding passes
 * build/sil/agnav_megaatmega2560.elf, see agnav_host/sil/avr_build.py), else $AGNAV_AVR_ELF, else
 * .pio/build/megaatmega2560/firmware.elf relative to the working directory.
 *
 * Time. sil_time_us() = CPU cycles since power-on / 16. sil_step_to() runs the core
 * instruction by instruction to the first instruction boundary at or after the target
 * cycle (so the time reached is the target, the core may be up to one instruction, < 1 us,
 * past it). The firmware's own clock is Timer5 (4 us ticks): that, not this API, limits
 * its time resolution. sil_set_tick_us() is accepted and ignored: the real main loop runs
 * free; sil_loop_passes() is 0 (the loop is inlined into main()).
 *
 * Timed events (encoder and echo edges) sit in a min-heap on (t, queueing order); the core
 * stops at each event's cycle and the edge is applied to the pins, where the real
 * interrupt hardware (simavr's PCINT0 / INT0..3, and the PCINT2 model below) takes over.
 *
 * Sonar. A trigger is the falling edge of a trigger pin (PA0..7 sonars 0..7, PC0..3 8..11),
 * logged with its own time. With stop_on_trigger, sil_step_to() returns
 * SIL_AVR_TRIGGER_SETTLE_US after the last trigger of a burst (a ring group fires its
 * sensors one after the other, 10 us pulse each), well before any echo can rise.
 *
 * UART0 is the link. Bytes written by sil_uart_write() wait in a queue and are fed to
 * simavr's receiver while its input FIFO has room (XOFF / FIFO full stops the feed; XON and a
 * one-byte-time pacing timer resume it: simavr 1.6 raises XON only on UCSR0A polls); simavr
 * then delivers them at the programmed byte time (57600 baud: UBRR0 = 34, U2X0: 10 bits x 35 x 8
 * cycles = 175 us; set here because simavr computes it before U2X0 is written). Bytes the
 * firmware puts in UDR0 are captured in a ring for sil_uart_read().
 * The host side runs at its nominal rate, sil_avr_set_host_baud() (default 57600; 0: it follows
 * the firmware), the firmware at the one its UBRR0/U2X0 give: each byte in either direction is
 * re-read with the receiving side's bit sampling (avr_board_model.h), so a rate off by more than
 * the receiver tolerates garbles bytes (counted: sil_avr_uart_link_stats()); a framing error
 * reaches the firmware as FE0. sil_avr_set_uart_divisor() overwrites UBRR0/U2X0 (a wrong divisor
 * without rebuilding the ELF).
 *
 * EEPROM: a byte the firmware programs keeps EECR.EEPE set for 3.3 ms (Table 8-1;
 * sil_avr_set_eeprom_write_us(), 0 = simavr's instant write), so a busy-wait on EEPE stalls the
 * main loop as on the chip. sil_avr_eeprom_writes() counts the bytes programmed.
 * sil_avr_control_gap_max_us() is the longest time between two control ticks (throttle /
 * left-duty compare writes, avr_board_model.h), read and reset: "worst control period", e.g.
 * during a save (agnav_host.sil.storage_timing). sil_avr_control_ticks() counts the ticks.
 *
 * simavr 1.6 corrections, so the model behaves like the chip: TIFRn writes clear only the
 * flags written as 1 (simavr clears all: a Timer5 overflow pending under cli() was lost and the
 * watchdog reset the board); INTn low-level polling is off (the firmware never uses level
 * mode; simavr polled PE4's servo pulse every cycle: 5x slower); sleep is fast-forwarded
 * without usleep() and bounded at each stop cycle. Core resets (watchdog) are counted:
 * sil_avr_resets().
 *
 * Outputs are read back from the timer registers: servo us = OCR3A / OCR3B / 2 (Timer3 at
 * 2 ticks per us), H-bridge duty = OCR4A / OCR4B, direction = PH5 / PH6. Watchdog kicks are
 * the WDR instructions executed, the timeout is WDTCSR's prescaler.
 *
 * Parameters. main.c's list of parameter groups (PARAM_GROUPS, in flash: one uint16 pointer per
 * group to {uint16 rows pointer, uint8 count}) is found by its ELF symbol; each group's rows (in
 * flash: name[17], index uint8, type uint8, value pointer uint16, min, max, default int32 = 33
 * bytes a row) are read and put in index order, the order of PARAM_VALUE and of the EEPROM
 * record. sil_param_get/set read and write the modules' variables in the AVR's RAM
 * (range-checked like params_set()); sil_param_save() writes params.c's EEPROM record
 * {magic 0xA61D, count, int32 values, CRC-16/CCITT-FALSE} at PARAMS_EEPROM_ADDR, which the
 * firmware loads at its next boot. sil_reboot() keeps the EEPROM and powers on a new core.
 */
#include "sil_api.h"
#include "sil_eeprom_map.h"
#include "sil_events.h"

#include "avr_board_model.h"

#include <simavr/avr_eeprom.h>
#include <simavr/avr_extint.h>
#include <simavr/avr_ioport.h>
#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>
#include <simavr/sim_cycle_timers.h>
#include <simavr/sim_elf.h>
#include <simavr/sim_interrupts.h>
#include <simavr/sim_irq.h>

#include <fcntl.h>
#include <gelf.h>
#include <libelf.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#define PARAMS_MAGIC 0xA61Du        /* params.c */
#define PARAM_ROW_BYTES 33u         /* avr-gcc layout of param_def_t */
#define PARAM_GROUP_BYTES 3u        /* avr-gcc layout of param_group_t */
#define PARAMS_MAX 64u

#define F_CPU_HZ 16000000ull
#define CYC_PER_US 16ull
#define SIL_AVR_TRIGGER_SETTLE_US 50u
#define BOOT_LIMIT_US 200000u
#define UART_Q 65536u /* power of two */
#define EE_SIZE 4096u

/* ATmega2560 data-space addresses */
#define REG_PCIFR 0x3B
#define REG_WDTCSR 0x60
#define REG_PCICR 0x68
#define REG_PCMSK2 0x6D
#define REG_OCR3AL 0x98
#define REG_OCR3BL 0x9A
#define REG_OCR4AL 0xA8
#define REG_OCR4BL 0xAA
#define REG_UCSR0B 0xC1
#define REG_PORTH 0x102
#define RXEN0_BIT 4u
#define OPCODE_WDR 0x95A8u

#define REG_MCUSR 0x54u /* WDRF bit 3, BORF 2, EXTRF 1, PORF 0 */

typedef sil_event_t ev_t;

typedef struct {
    char name[17];
    uint8_t type;
    uint16_t ptr;
    int32_t min, max;
} prow_t;

static struct {
    int stop_on_trigger;
    uint32_t tick_us;
    uint64_t ev_seq;
    uint32_t ev_n, late;
    sil_trigger_queue_t trig;
    uint32_t trig_new;
    uint32_t trig_count[12];
    uint64_t limit_cycle;    /* run to this cycle (target or next event) */
    uint64_t run_until;      /* min(limit, trigger settle deadline) */
    uint64_t trig_deadline;  /* 0 none */
    uint32_t wdt_kicks;
    uint64_t instr;          /* avr->run() calls (instructions + sleep steps) */
    int dead;                /* core crashed / stopped: time still advances, nothing runs */
    /* UART */
    uint8_t rxq[UART_Q];
    uint32_t rx_head, rx_tail; /* free-running */
    int xoff, pumping;
    uint8_t txq[UART_Q];
    uint32_t tx_head, tx_tail;
    uint32_t tx_lost;
    uint32_t log_errors;
    uint32_t resets;         /* core resets after power-on (watchdog, ...) */
    /* fault injection (sil_api.h) */
    uint8_t enc_fault[4], enc_ab[4], sonar_fault[12];
    uint16_t world_echo_high; /* bit i: echo line i is high on a pulse of the world's (not an injected one) */
    uint64_t last_kick_cycle;
    uint32_t kick_gap_max_us;
    avr_model_link_t link;   /* host side of UART0 and its byte counts */
} S;

static uint32_t g_host_baud = AVR_MODEL_HOST_BAUD_DEFAULT; /* kept across sil_init() */
static uint32_t g_eeprom_write_us = AVR_MODEL_EEPROM_WRITE_US;

static ev_t s_heap[SIL_EVENT_MAX];
static avr_t *g_avr;
static elf_firmware_t g_fw;
static int g_fw_loaded;
static char g_elf_path[4096];
static prow_t g_params[PARAMS_MAX];
static int g_param_n = -1; /* -1 table not found */
static avr_irq_t *g_enc_a[4], *g_enc_b[4], *g_echo[12], *g_uart_in;
static avr_int_vector_t g_pcint2;

/* ---- event heap (same as the native SIL) ------------------------------------------------ */
static int ev_push(uint8_t kind, uint8_t idx, uint8_t val, uint64_t t_us)
{
    return sil_ev_push(s_heap, SIL_EVENT_MAX, &S.ev_n, &S.ev_seq, kind, idx, val, t_us);
}

static ev_t ev_pop(void) { return sil_ev_pop(s_heap, &S.ev_n); }

/* ---- ELF: firmware image and the parameter groups ---------------------------------------------- */
static const char *elf_path(void)
{
    if (g_elf_path[0] != '\0') {
        return g_elf_path;
    }
    const char *e = getenv("AGNAV_AVR_ELF");
    return e != NULL && e[0] != '\0' ? e : ".pio/build/megaatmega2560/firmware.elf";
}

void sil_avr_set_elf(const char *path)
{
    snprintf(g_elf_path, sizeof g_elf_path, "%s", path != NULL ? path : "");
    g_fw_loaded = 0;
    g_param_n = -1;
}

static uint32_t find_groups_symbol(const char *path, uint32_t *size)
{
    uint32_t addr = 0;
    *size = 0;
    if (elf_version(EV_CURRENT) == EV_NONE) {
        return 0;
    }
    int fd = open(path, O_RDONLY);
    if (fd < 0) {
        return 0;
    }
    Elf *e = elf_begin(fd, ELF_C_READ, NULL);
    Elf_Scn *scn = NULL;
    while (e != NULL && (scn = elf_nextscn(e, scn)) != NULL) {
        GElf_Shdr sh;
        if (gelf_getshdr(scn, &sh) == NULL || sh.sh_type != SHT_SYMTAB) {
            continue;
        }
        Elf_Data *d = elf_getdata(scn, NULL);
        size_t n = sh.sh_entsize ? sh.sh_size / sh.sh_entsize : 0;
        for (size_t i = 0; d != NULL && i < n; i++) {
            GElf_Sym sym;
            if (gelf_getsym(d, (int)i, &sym) == NULL) {
                continue;
            }
            const char *nm = elf_strptr(e, sh.sh_link, sym.st_name);
            if (nm != NULL && (strcmp(nm, "PARAM_GROUPS") == 0 || strncmp(nm, "PARAM_GROUPS.", 13) == 0) &&
                GELF_ST_TYPE(sym.st_info) == STT_OBJECT) {
                addr = (uint32_t)sym.st_value;
                *size = (uint32_t)sym.st_size;
            }
        }
    }
    if (e != NULL) {
        elf_end(e);
    }
    close(fd);
    return addr;
}

static uint16_t flash_u16(uint32_t a) { return (uint16_t)(g_fw.flash[a] | (g_fw.flash[a + 1u] << 8)); }

static int32_t flash_i32(uint32_t a)
{
    return (int32_t)((uint32_t)g_fw.flash[a] | (uint32_t)g_fw.flash[a + 1u] << 8 | (uint32_t)g_fw.flash[a + 2u] << 16 |
                     (uint32_t)g_fw.flash[a + 3u] << 24);
}

static int in_flash(uint32_t addr, uint32_t len)
{
    return addr >= g_fw.flashbase && addr + len <= g_fw.flashbase + g_fw.flashsize;
}

/* The rows of every group at addr (size bytes of group pointers), at g_params[index]: the row count,
 * or -1 when the groups are not there or their indices are not 0..n-1 each once. */
static int read_param_groups(uint32_t addr, uint32_t size)
{
    if (addr == 0u || size == 0u || size % 2u != 0u || !in_flash(addr, size)) {
        return -1;
    }
    uint8_t seen[PARAMS_MAX];
    memset(seen, 0, sizeof seen);
    uint32_t n = 0;
    for (uint32_t g = 0; g < size / 2u; g++) {
        uint32_t grp = flash_u16(addr - g_fw.flashbase + 2u * g);
        if (!in_flash(grp, PARAM_GROUP_BYTES)) {
            return -1;
        }
        uint32_t rows = flash_u16(grp - g_fw.flashbase);
        uint32_t count = g_fw.flash[grp - g_fw.flashbase + 2u];
        if (!in_flash(rows, count * PARAM_ROW_BYTES)) {
            return -1;
        }
        for (uint32_t k = 0; k < count; k++) {
            uint32_t a = rows - g_fw.flashbase + k * PARAM_ROW_BYTES;
            uint8_t index = g_fw.flash[a + 17u];
            if (index >= PARAMS_MAX || seen[index]) {
                return -1;
            }
            seen[index] = 1;
            prow_t *r = &g_params[index];
            memcpy(r->name, &g_fw.flash[a], 17);
            r->name[16] = '\0';
            r->type = g_fw.flash[a + 18u];
            r->ptr = flash_u16(a + 19u);
            r->min = flash_i32(a + 21u);
            r->max = flash_i32(a + 25u);
            n++;
        }
    }
    for (uint32_t i = 0; i < n; i++) {
        if (!seen[i]) {
            return -1; /* a gap */
        }
    }
    return (int)n;
}

static int load_elf(void)
{
    if (g_fw_loaded) {
        return 0;
    }
    const char *path = elf_path();
    memset(&g_fw, 0, sizeof g_fw);
    /* libsimavr's ELF loader chats on stdout */
    fflush(stdout);
    int saved = dup(1);
    int devnull = open("/dev/null", O_WRONLY);
    if (saved >= 0 && devnull >= 0) {
        dup2(devnull, 1);
    }
    int rc = elf_read_firmware(path, &g_fw);
    fflush(stdout);
    if (saved >= 0 && devnull >= 0) {
        dup2(saved, 1);
    }
    if (saved >= 0) {
        close(saved);
    }
    if (devnull >= 0) {
        close(devnull);
    }
    if (rc != 0 || g_fw.flash == NULL) {
        fprintf(stderr, "avr_sil: cannot read ELF '%s'\n", path);
        return -1;
    }
    uint32_t size = 0;
    uint32_t groups = find_groups_symbol(path, &size);
    g_param_n = read_param_groups(groups, size);
    g_fw_loaded = 1;
    return 0;
}

/* ---- simavr plumbing --------------------------------------------------------------------- */
static void quiet_logger(avr_t *avr, const int level, const char *fmt, va_list ap)
{
    (void)avr;
    (void)fmt;
    (void)ap;
    if (level <= LOG_ERROR) {
        S.log_errors++;
    }
}

static void no_sleep(avr_t *avr, avr_cycle_count_t how_long)
{
    (void)avr; /* simavr's raw mode would usleep() to stay in real time: never here */
    (void)how_long;
}

/* Bounds a sleep's fast-forward to the cycle where run_core() must stop. It re-arms every
 * cycle once due (run_core cancels it): when the firmware executes SLEEP on the very cycle the
 * bound is reached, simavr fires the due timers and then jumps to the *next* one, which would
 * otherwise be a timer/UART event hundreds of cycles later. */
static avr_cycle_count_t wake(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    (void)param;
    return when + 1u;
}

static avr_uart_t *g_uart0;
DEFINE_FIFO(uint16_t, uart_fifo); /* the accessors of avr_uart.h's input FIFO (static inline) */

static avr_cycle_count_t uart_pace(avr_t *avr, avr_cycle_count_t when, void *param);

static void uart_fix_baud(void) { avr_model_uart0_fix_baud(g_avr, g_uart0); }

/* Feed queued link bytes to simavr's receiver while its input FIFO has room (XOFF / a full
 * FIFO stops it). simavr 1.6 signals XON only when the firmware polls UCSR0A, which this
 * interrupt-driven firmware never does, so a pacing timer (one byte time) tops the FIFO up
 * while bytes wait. */
static void uart_pump(void)
{
    if (g_avr == NULL || S.pumping || !(g_avr->data[REG_UCSR0B] & (1u << RXEN0_BIT))) {
        return;
    }
    S.pumping = 1;
    uart_fix_baud();
    while (S.rx_tail != S.rx_head) {
        if (g_uart0 != NULL ? uart_fifo_isfull(&g_uart0->input) : S.xoff) {
            break;
        }
        uint8_t b = S.rxq[S.rx_tail & (UART_Q - 1u)];
        S.rx_tail++;
        int v = avr_model_link_to_avr(&S.link, g_avr, b);
        if (v >= 0) {
            avr_raise_irq(g_uart_in, (uint32_t)v);
        }
    }
    if (S.rx_tail != S.rx_head && avr_cycle_timer_status(g_avr, uart_pace, NULL) == 0) {
        avr_cycle_count_t per = g_uart0 != NULL && g_uart0->cycles_per_byte ? g_uart0->cycles_per_byte : 2720u;
        avr_cycle_timer_register(g_avr, per, uart_pace, NULL);
    }
    S.pumping = 0;
}

static avr_cycle_count_t uart_pace(avr_t *avr, avr_cycle_count_t when, void *param)
{
    (void)avr;
    (void)when;
    (void)param;
    uart_pump(); /* re-registers itself while bytes wait */
    return 0;
}

static void on_uart_out(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    int v = avr_model_link_to_host(&S.link, g_avr, (uint8_t)value);
    if (v < 0) {
        return; /* the host saw no frame */
    }
    if (S.tx_head - S.tx_tail < UART_Q) {
        S.txq[S.tx_head & (UART_Q - 1u)] = (uint8_t)v;
        S.tx_head++;
    } else {
        S.tx_lost++;
    }
}

static void on_xon(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    if (value) {
        S.xoff = 0;
        uart_pump();
    }
}

static void on_xoff(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)param;
    S.xoff = value != 0;
}

static uint64_t now_cycle(void) { return g_avr != NULL ? g_avr->cycle : 0u; }

static void on_trigger(struct avr_irq_t *irq, uint32_t value, void *param)
{
    unsigned idx = (unsigned)(uintptr_t)param;
    if (value != 0 || irq->value == 0) {
        return; /* the falling edge ends the trigger pulse */
    }
    (void)sil_trig_push(&S.trig, (uint8_t)idx, now_cycle() / CYC_PER_US);
    S.trig_count[idx]++;
    S.trig_new++;
    if (S.sonar_fault[idx] == SIL_SONAR_ZERO) {
        uint64_t rise = now_cycle() / CYC_PER_US + SIL_SONAR_ZERO_DELAY_US;
        (void)ev_push(SIL_EV_ECHO_FAULT, (uint8_t)idx, 1u, rise);
        (void)ev_push(SIL_EV_ECHO_FAULT, (uint8_t)idx, 0u, rise + SIL_SONAR_ZERO_ECHO_US);
    }
    if (S.stop_on_trigger) {
        uint64_t dl = now_cycle() + SIL_AVR_TRIGGER_SETTLE_US * CYC_PER_US;
        S.trig_deadline = dl;
        S.run_until = dl < S.limit_cycle ? dl : S.limit_cycle;
        avr_cycle_timer_register(g_avr, dl - now_cycle(), wake, (void *)1); /* own slot: keeps run_core's */
    }
}

static void enc_set(uint8_t i, uint8_t ab)
{
    if (g_avr == NULL || i >= 4u) {
        return;
    }
    uint8_t a = (uint8_t)((ab >> 1) & 1u), b = (uint8_t)(ab & 1u);
    uint8_t before = (uint8_t)((g_enc_a[i]->value ? 1u : 0u) | (g_enc_b[i]->value ? 2u : 0u));
    avr_raise_irq(g_enc_a[i], a);
    avr_raise_irq(g_enc_b[i], b);
    uint8_t after = (uint8_t)(a | (b << 1));
    uint8_t changed = (uint8_t)((before ^ after) << (2u * i));
    if (changed & g_avr->data[REG_PCMSK2]) {
        avr_raise_interrupt(g_avr, &g_pcint2);
    }
}

static void echo_set(uint8_t i, uint8_t level)
{
    if (g_avr != NULL && i < 12u) {
        avr_raise_irq(g_echo[i], level ? 1u : 0u);
    }
}

/* Fault filters in front of the pins (same semantics as the native SIL). */
static void enc_deliver(uint8_t i, uint8_t ab)
{
    if (i >= 4u || S.enc_fault[i] == SIL_ENC_STUCK || S.enc_fault[i] == SIL_ENC_DISCONNECTED) {
        return;
    }
    if (S.enc_fault[i] == SIL_ENC_NOISE) {
        ab = (uint8_t)(S.enc_ab[i] ^ 3u);
    }
    S.enc_ab[i] = ab;
    enc_set(i, ab);
}

static void echo_deliver(uint8_t i, uint8_t level, int injected)
{
    if (i < 12u && !injected) {
        uint16_t bit = (uint16_t)(1u << i);
        int in_flight = level == 0u && (S.world_echo_high & bit) != 0u; /* a pulse high when the fault began ends */
        if (S.sonar_fault[i] != SIL_FAULT_NONE && !in_flight) {
            return;
        }
        S.world_echo_high = (uint16_t)(level != 0u ? S.world_echo_high | bit : S.world_echo_high & ~bit);
    }
    echo_set(i, level);
}

static void ee_get(uint32_t addr, uint8_t *dst, uint32_t len)
{
    if (g_avr == NULL || len == 0u) {
        return;
    }
    avr_eeprom_desc_t d = {dst, (uint16_t)addr, len};
    avr_ioctl(g_avr, AVR_IOCTL_EEPROM_GET, &d);
}

static void ee_set(uint32_t addr, const uint8_t *src, uint32_t len)
{
    if (g_avr == NULL || len == 0u) {
        return;
    }
    avr_eeprom_desc_t d = {(uint8_t *)src, (uint16_t)addr, len};
    avr_ioctl(g_avr, AVR_IOCTL_EEPROM_SET, &d);
}

static void (*g_mcu_reset)(struct avr_t *avr);

/* avr_reset() after power-on: a watchdog reset (or the firmware jumping to 0 is NOT seen here). */
static void on_core_reset(struct avr_t *avr)
{
    S.resets++;
    if (g_mcu_reset != NULL) {
        g_mcu_reset(avr);
    }
    avr_model_no_level_poll(avr);
    avr_model_eeprom_after_reset(avr);
}

/* ---- life cycle ----------------------------------------------------------------------------- */
uint32_t sil_api_version(void) { return SIL_API_VERSION; }

void sil_init(void)
{
    memset(&S, 0, sizeof S);
    S.link.host_baud = g_host_baud;
    S.tick_us = 100u;
    S.stop_on_trigger = 1;
    avr_global_logger_set(quiet_logger);
    if (g_avr != NULL) {
        avr_terminate(g_avr);
        g_avr = NULL; /* the avr_t itself is leaked (a few KB per power-on) */
    }
    if (load_elf() != 0) {
        return;
    }
    g_avr = avr_make_mcu_by_name("atmega2560");
    if (g_avr == NULL) {
        return;
    }
    avr_init(g_avr);
    g_avr->log = LOG_NONE;
    avr_load_firmware(g_avr, &g_fw);
    g_avr->frequency = (uint32_t)F_CPU_HZ;
    g_avr->sleep = no_sleep;

    uint32_t flags = 0;
    avr_ioctl(g_avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)(AVR_UART_FLAG_STDIO | AVR_UART_FLAG_POLL_SLEEP);
    avr_ioctl(g_avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT), on_uart_out, NULL);
    avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON), on_xon, NULL);
    avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF), on_xoff, NULL);
    g_uart_in = avr_io_getirq(g_avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    g_uart0 = avr_model_uart0(g_avr);

    /* simavr's ATmega2560 has no PCINT2 (PORTK): modelled as in avr_harness.c. Vector 11,
     * PCICR 0x68 bit 2 enable, PCIFR 0x3B bit 2 flag. */
    memset(&g_pcint2, 0, sizeof g_pcint2);
    g_pcint2.enable = (avr_regbit_t)AVR_IO_REGBIT(REG_PCICR, 2);
    g_pcint2.raised = (avr_regbit_t)AVR_IO_REGBIT(REG_PCIFR, 2);
    g_pcint2.vector = 11;
    avr_register_vector(g_avr, &g_pcint2);
    for (unsigned i = 0; i < 4u; i++) {
        g_enc_a[i] = avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ('K'), (int)(2u * i));
        g_enc_b[i] = avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ('K'), (int)(2u * i + 1u));
        avr_raise_irq(g_enc_a[i], 0);
        avr_raise_irq(g_enc_b[i], 0);
    }
    for (unsigned i = 0; i < 12u; i++) {
        char trig_port = i < 8u ? 'A' : 'C', echo_port = i < 8u ? 'B' : 'D';
        unsigned pin = i < 8u ? i : i - 8u;
        avr_irq_register_notify(avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ(trig_port), (int)pin), on_trigger,
                                (void *)(uintptr_t)i);
        g_echo[i] = avr_io_getirq(g_avr, AVR_IOCTL_IOPORT_GETIRQ(echo_port), (int)pin);
    }
    avr_model_no_level_poll(g_avr);
    avr_model_hook_tifr(g_avr);
    avr_model_eeprom_timing(g_avr, g_eeprom_write_us);
    avr_model_watch_control(g_avr);
    g_mcu_reset = g_avr->reset;
    g_avr->reset = on_core_reset;
    g_avr->data[REG_MCUSR] = 0x01u; /* PORF, as the chip after a power-on (simavr leaves 0) */
}

/* Run the core until run_until (an instruction boundary at or after it). */
static void run_core(void)
{
    avr_t *avr = g_avr;
    if (avr == NULL) {
        return;
    }
    if (S.dead) {
        if (avr->cycle < S.run_until) {
            avr->cycle = S.run_until;
        }
        return;
    }
    if (avr->cycle < S.run_until) {
        avr_cycle_timer_register(avr, S.run_until - avr->cycle, wake, NULL);
    }
    while (avr->cycle < S.run_until) {
        uint32_t pc = avr->pc;
        if ((uint16_t)(avr->flash[pc] | (avr->flash[pc + 1u] << 8)) == OPCODE_WDR) {
            if (S.wdt_kicks != 0u) {
                uint64_t gap_us = (avr->cycle - S.last_kick_cycle) / CYC_PER_US;
                if (gap_us > S.kick_gap_max_us) {
                    S.kick_gap_max_us = (uint32_t)gap_us;
                }
            }
            S.last_kick_cycle = avr->cycle;
            S.wdt_kicks++;
        }
        avr->run(avr);
        S.instr++;
        if (avr->state == cpu_Crashed || avr->state == cpu_Done) {
            S.dead = 1;
            avr->cycle = S.run_until;
            break;
        }
    }
    avr_cycle_timer_cancel(avr, wake, NULL);
    avr_cycle_timer_cancel(avr, wake, (void *)1);
}

void sil_boot(void)
{
    if (g_avr == NULL) {
        return;
    }
    /* agnav_setup() ends with hal_watchdog_start(): boot is done when WDTCSR has WDE. */
    uint64_t limit = BOOT_LIMIT_US * CYC_PER_US;
    while (!(g_avr->data[REG_WDTCSR] & 0x08u) && g_avr->cycle < limit && !S.dead) {
        S.limit_cycle = S.run_until = g_avr->cycle + 16u;
        run_core();
    }
    uart_fix_baud();
    S.trig_deadline = 0;
}

void sil_reset(void)
{
    sil_init();
    sil_boot();
}

void sil_reboot(void)
{
    static uint8_t keep[EE_SIZE];
    ee_get(0, keep, EE_SIZE);
    sil_init();
    ee_set(0, keep, EE_SIZE);
    sil_boot();
}

/* ---- time -------------------------------------------------------------------------------------- */
uint64_t sil_time_us(void) { return now_cycle() / CYC_PER_US; }

void sil_set_tick_us(uint32_t tick_us) { S.tick_us = tick_us; }
void sil_set_stop_on_trigger(int on) { S.stop_on_trigger = on != 0; }
uint64_t sil_loop_passes(void) { return 0u; }

static void deliver_due(void)
{
    uint64_t now = sil_time_us();
    while (S.ev_n > 0u && s_heap[0].t_us <= now) {
        ev_t e = ev_pop();
        if (e.t_us < now) {
            S.late++;
        }
        if (e.kind == SIL_EV_ENCODER) {
            enc_deliver(e.idx, e.val);
        } else {
            echo_deliver(e.idx, e.val, e.kind == SIL_EV_ECHO_FAULT);
        }
    }
}

uint64_t sil_step_to(uint64_t target)
{
    if (g_avr == NULL) {
        return 0u;
    }
    deliver_due();
    uart_pump();
    S.trig_new = 0u;
    S.trig_deadline = 0u;
    while (sil_time_us() < target) {
        uint64_t lim = target * CYC_PER_US;
        if (S.ev_n > 0u && s_heap[0].t_us * CYC_PER_US < lim) {
            lim = s_heap[0].t_us * CYC_PER_US;
        }
        S.limit_cycle = lim;
        S.run_until = S.trig_deadline != 0u && S.trig_deadline < lim ? S.trig_deadline : lim;
        if (S.run_until > g_avr->cycle) {
            run_core();
        }
        deliver_due();
        uart_pump();
        if (S.stop_on_trigger && S.trig_new != 0u && S.trig_deadline != 0u && g_avr->cycle >= S.trig_deadline) {
            break;
        }
    }
    S.trig_deadline = 0u;
    return sil_time_us();
}

uint32_t sil_step(uint32_t dt_us)
{
    uint64_t t0 = sil_time_us();
    return (uint32_t)(sil_step_to(t0 + dt_us) - t0);
}

/* ---- serial ---------------------------------------------------------------------------------------- */
uint32_t sil_uart_write(const uint8_t *data, uint32_t len)
{
    uint32_t n = 0;
    while (n < len && S.rx_head - S.rx_tail < UART_Q) {
        S.rxq[S.rx_head & (UART_Q - 1u)] = data[n++];
        S.rx_head++;
    }
    uart_pump();
    return n;
}

uint32_t sil_uart_read(uint8_t *buf, uint32_t max)
{
    uint32_t n = 0;
    while (n < max && S.tx_tail != S.tx_head) {
        buf[n++] = S.txq[S.tx_tail & (UART_Q - 1u)];
        S.tx_tail++;
    }
    return n;
}

/* ---- encoders and sonar ------------------------------------------------------------------------------ */
void sil_encoder_edge(uint8_t idx, uint8_t ab) { enc_deliver(idx, ab); }

uint32_t sil_queue_encoder_edges(uint8_t idx, const uint64_t *t_us, const uint8_t *ab, uint32_t n)
{
    return sil_ev_push_edges(s_heap, SIL_EVENT_MAX, &S.ev_n, &S.ev_seq, idx, t_us, ab, n);
}

int sil_queue_echo(uint8_t idx, uint64_t t_us, uint8_t level) { return ev_push(SIL_EV_ECHO, idx, level != 0u, t_us); }

uint32_t sil_take_triggers(uint8_t *idx, uint64_t *t_us, uint32_t max) { return sil_trig_take(&S.trig, idx, t_us, max); }

uint32_t sil_sonar_trigger_count(uint8_t idx) { return idx < 12u ? S.trig_count[idx] : 0u; }
void sil_sonar_echo_edge(uint8_t idx, uint8_t level) { echo_deliver(idx, level, 0); }
uint32_t sil_pending_events(void) { return S.ev_n; }
uint32_t sil_late_events(void) { return S.late; }

/* ---- actuators ---------------------------------------------------------------------------------------- */
static uint16_t reg16(uint16_t lo) { return g_avr != NULL ? (uint16_t)(g_avr->data[lo] | (g_avr->data[lo + 1u] << 8)) : 0u; }

uint16_t sil_servo_us(uint8_t channel)
{
    if (channel > 1u) {
        return 0u;
    }
    return (uint16_t)(reg16(channel == 0u ? REG_OCR3AL : REG_OCR3BL) / 2u);
}

uint8_t sil_pwm_duty(uint8_t channel)
{
    if (channel > 1u || g_avr == NULL) {
        return 0u;
    }
    return g_avr->data[channel == 0u ? REG_OCR4AL : REG_OCR4BL];
}

uint8_t sil_pwm_reverse(uint8_t channel)
{
    if (channel > 1u || g_avr == NULL) {
        return 0u;
    }
    return (uint8_t)((g_avr->data[REG_PORTH] >> (5u + channel)) & 1u);
}

static uint16_t wdt_timeout_ms(void)
{
    if (g_avr == NULL) {
        return 0u;
    }
    uint8_t v = g_avr->data[REG_WDTCSR];
    if (!(v & 0x08u)) {
        return 0u;
    }
    static const uint16_t ms[10] = {15, 30, 60, 120, 250, 500, 1000, 2000, 4000, 8000};
    uint8_t p = (uint8_t)((v & 0x07u) | ((v >> 2) & 0x08u));
    return p < 10u ? ms[p] : 0u;
}

void sil_outputs(sil_outputs_t *out)
{
    memset(out, 0, sizeof *out);
    for (uint8_t i = 0; i < 2u; i++) {
        out->servo_us[i] = sil_servo_us(i);
        out->duty[i] = sil_pwm_duty(i);
        out->reverse[i] = sil_pwm_reverse(i);
    }
    out->wdt_kicks = S.wdt_kicks;
    out->wdt_timeout_ms = wdt_timeout_ms();
}

/* ---- parameters and EEPROM ------------------------------------------------------------------------------ */
static int param_index(const char *name)
{
    for (int i = 0; i < g_param_n; i++) {
        if (strncmp(g_params[i].name, name, 16) == 0 && (strlen(name) <= 16u)) {
            return i;
        }
    }
    return -1;
}

static int32_t param_read(int i)
{
    const prow_t *r = &g_params[i];
    const uint8_t *v = g_avr->data + r->ptr;
    switch (r->type) {
    case 0: return v[0];
    case 1: return (uint16_t)(v[0] | (v[1] << 8));
    case 2: return (int16_t)(v[0] | (v[1] << 8));
    case 4: return (int8_t)v[0];
    default: return (int32_t)((uint32_t)v[0] | (uint32_t)v[1] << 8 | (uint32_t)v[2] << 16 | (uint32_t)v[3] << 24);
    }
}

int sil_param_set(const char *name, int32_t value)
{
    int i = g_avr != NULL ? param_index(name) : -1;
    if (i < 0) {
        return -1; /* PARAMS_UNKNOWN */
    }
    const prow_t *r = &g_params[i];
    if (value < r->min || value > r->max) {
        return -2; /* PARAMS_OUT_OF_RANGE */
    }
    uint8_t *v = g_avr->data + r->ptr;
    unsigned n = (r->type == 0 || r->type == 4) ? 1u : r->type == 3 ? 4u : 2u; /* U8 I8 / I32 / 16-bit */
    for (unsigned k = 0; k < n; k++) {
        v[k] = (uint8_t)((uint32_t)value >> (8u * k));
    }
    return 0;
}

int sil_param_get(const char *name, int32_t *out)
{
    int i = g_avr != NULL ? param_index(name) : -1;
    if (i < 0) {
        return -1;
    }
    *out = param_read(i);
    return 0;
}

static uint16_t crc16_ccitt_false(uint16_t crc, const uint8_t *p, uint32_t n)
{
    while (n-- > 0u) {
        crc ^= (uint16_t)(*p++ << 8);
        for (int b = 0; b < 8; b++) {
            crc = (uint16_t)((crc & 0x8000u) ? (((unsigned)crc << 1) ^ 0x1021u) : ((unsigned)crc << 1));
        }
    }
    return crc;
}

int sil_param_save(void)
{
    if (g_avr == NULL || g_param_n < 0) {
        return -3; /* PARAMS_STORAGE */
    }
    uint8_t rec[4u + 4u * PARAMS_MAX + 2u];
    uint32_t n = 0;
    rec[n++] = (uint8_t)(PARAMS_MAGIC & 0xFFu);
    rec[n++] = (uint8_t)(PARAMS_MAGIC >> 8);
    rec[n++] = (uint8_t)((unsigned)g_param_n & 0xFFu);
    rec[n++] = (uint8_t)((unsigned)g_param_n >> 8);
    for (int i = 0; i < g_param_n; i++) {
        uint32_t v = (uint32_t)param_read(i);
        for (unsigned k = 0; k < 4u; k++) {
            rec[n++] = (uint8_t)(v >> (8u * k));
        }
    }
    uint16_t crc = crc16_ccitt_false(0xFFFFu, rec, n);
    rec[n++] = (uint8_t)(crc & 0xFFu);
    rec[n++] = (uint8_t)(crc >> 8);
    ee_set(SIL_EEPROM_PARAMS_ADDR, rec, n);
    uint8_t back[2] = {0, 0};
    ee_get(SIL_EEPROM_PARAMS_ADDR + n - 2u, back, 2);
    return back[0] == rec[n - 2u] && back[1] == rec[n - 1u] ? 0 : -3;
}

uint32_t sil_eeprom_size(void) { return EE_SIZE; }
void sil_eeprom_read(uint32_t addr, uint8_t *dst, uint32_t len)
{
    if (addr < EE_SIZE) {
        ee_get(addr, dst, len > EE_SIZE - addr ? EE_SIZE - addr : len);
    }
}
void sil_eeprom_write(uint32_t addr, const uint8_t *src, uint32_t len)
{
    if (addr < EE_SIZE) {
        ee_set(addr, src, len > EE_SIZE - addr ? EE_SIZE - addr : len);
    }
}

/* ---- AVR-only extras ---------------------------------------------------------------------------------------- */
int sil_avr_param_count(void) { return g_param_n; }
const char *sil_avr_param_name(int i) { return i >= 0 && i < g_param_n ? g_params[i].name : NULL; }
uint64_t sil_avr_cycles(void) { return now_cycle(); }
uint64_t sil_avr_instructions(void) { return S.instr; }
int sil_avr_state(void) { return g_avr == NULL ? -1 : S.dead ? (int)g_avr->state : 0; } /* 0 ok */
uint32_t sil_avr_log_errors(void) { return S.log_errors; }
uint32_t sil_avr_resets(void) { return S.resets; }
uint32_t sil_avr_uart_rx_pending(void) { return S.rx_head - S.rx_tail; }
uint32_t sil_avr_uart_tx_lost(void) { return S.tx_lost; }

void sil_avr_set_host_baud(uint32_t baud)
{
    g_host_baud = baud;
    S.link.host_baud = baud;
}

uint32_t sil_avr_host_baud(void) { return S.link.host_baud; }

/* out[6]: bytes to the host, of them garbled or lost, with a framing error; the same from the host. */
void sil_avr_uart_link_stats(uint32_t *out)
{
    out[0] = S.link.to_host;
    out[1] = S.link.to_host_garbled;
    out[2] = S.link.to_host_framing;
    out[3] = S.link.to_avr;
    out[4] = S.link.to_avr_garbled;
    out[5] = S.link.to_avr_framing;
}

/* UBRR0 (12 bits) and U2X0 as if the firmware had written them; the byte time follows. */
void sil_avr_set_uart_divisor(uint32_t ubrr, int u2x)
{
    if (g_avr == NULL) {
        return;
    }
    g_avr->data[0xC4] = (uint8_t)(ubrr & 0xFFu);
    g_avr->data[0xC5] = (uint8_t)((ubrr >> 8) & 0x0Fu);
    g_avr->data[0xC0] = (uint8_t)((g_avr->data[0xC0] & ~0x02u) | (u2x ? 0x02u : 0u));
    uart_fix_baud();
}

void sil_avr_set_eeprom_write_us(uint32_t us)
{
    g_eeprom_write_us = us;
    if (g_avr != NULL) {
        avr_model_eeprom_timing(g_avr, us);
    }
}

uint32_t sil_avr_eeprom_writes(void) { return avr_model_eeprom_writes(); }
uint32_t sil_avr_control_ticks(void) { return avr_model_control_ticks(); }
uint32_t sil_avr_control_gap_max_us(void) { return avr_model_control_gap_max_us(); }
const char *sil_avr_elf(void) { return elf_path(); }

/* ---- fault injection (sil_api.h; same semantics as the native SIL) ------------------------------- */
int sil_fault_encoder(uint8_t idx, int mode)
{
    if (idx >= 4u || mode < SIL_FAULT_NONE || mode > SIL_ENC_NOISE) {
        return -1;
    }
    S.enc_fault[idx] = (uint8_t)mode;
    if (mode == SIL_ENC_DISCONNECTED && S.enc_ab[idx] != 3u) {
        S.enc_ab[idx] = 3u;
        enc_set(idx, 3u);
    }
    return 0;
}

int sil_fault_sonar(uint8_t idx, int mode)
{
    if (idx >= 12u || mode < SIL_FAULT_NONE || mode > SIL_SONAR_ZERO) {
        return -1;
    }
    S.sonar_fault[idx] = (uint8_t)mode;
    return 0;
}

int sil_eeprom_record(int which, uint32_t *addr, uint32_t *len)
{
    return sil_eeprom_map(which, (uint32_t)(g_param_n > 0 ? g_param_n : 0), addr, len);
}

void sil_eeprom_corrupt(uint32_t addr, uint32_t len, uint8_t xor_mask)
{
    for (uint32_t i = 0; i < len && addr + i < EE_SIZE; i++) {
        uint8_t b;
        ee_get(addr + i, &b, 1u);
        b ^= xor_mask;
        ee_set(addr + i, &b, 1u);
    }
}

/* A real core reset (simavr's avr_reset: registers and RAM state, EEPROM kept), then the reset
 * flags the hardware would leave in MCUSR; the firmware's .init3 reads them. */
void sil_fault_reset(int cause)
{
    static const uint8_t FLAG[4] = {0x01u /* PORF */, 0x08u /* WDRF */, 0x02u /* EXTRF */, 0x04u /* BORF */};
    if (g_avr == NULL) {
        return;
    }
    avr_reset(g_avr); /* on_core_reset counts it */
    g_avr->data[REG_MCUSR] = cause >= 0 && cause < 4 ? FLAG[cause] : 0u;
    for (unsigned i = 0; i < 4u; i++) {
        S.enc_ab[i] = 0u;
        enc_set((uint8_t)i, 0u);
    }
    S.wdt_kicks = 0u;
}

uint32_t sil_resets(void) { return S.resets; }

uint32_t sil_kick_gap_max_us(void)
{
    uint32_t g = S.kick_gap_max_us;
    S.kick_gap_max_us = 0u;
    return g;
}

uint32_t sil_isr_burst(uint8_t idx, uint32_t n, uint32_t period_us)
{
    static const uint8_t GRAY[4] = {0u, 2u, 3u, 1u};
    uint8_t phase = 0u;
    for (uint8_t k = 0; k < 4u; k++) {
        if (GRAY[k] == S.enc_ab[idx < 4u ? idx : 0u]) {
            phase = k;
        }
    }
    uint64_t now = sil_time_us();
    uint32_t k = 0u;
    for (; k < n; k++) {
        phase = (uint8_t)((phase + 1u) & 3u);
        if (!ev_push(SIL_EV_ENCODER, idx, GRAY[phase], now + (uint64_t)(k + 1u) * period_us)) {
            break;
        }
    }
    return k;
}

void sil_set_isr_cost_us(uint32_t us) { (void)us; /* the real ISR costs real cycles */ }
