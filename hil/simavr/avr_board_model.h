/*
 * simavr 1.6 model corrections and additions for the AgNav ATmega2560 board (hil/simavr),
 * shared by avr_harness.c and avr_sil.c. Datasheet references: ATmega2560 datasheet 2549Q.
 *
 * Corrections (simavr differs from the chip):
 *   - TIFRn writes clear only the flags written as 1 (simavr clears every pending flag, which
 *     dropped a Timer5 overflow under idle sleep: the firmware clock lost 262 ms and the watchdog
 *     reset the board);
 *   - INTn low-level pin polling off (the firmware never uses level mode; simavr polled the
 *     PE4 servo pulse every cycle, 5-7x slower);
 *   - a sleeping core is fast-forwarded instead of being paced to wall-clock time;
 *   - UART0's byte time follows UBRR0 and U2X0 as the chip does (simavr computes it before U2X0
 *     is written and runs the UART at half speed);
 *   - EEPROM programming takes its time (8.3.1, Table 8-1: 26,368 cycles of the 8 MHz calibrated
 *     RC oscillator, 3.3 ms typical). simavr 1.6 writes the byte and clears EECR.EEPE in the same
 *     cycle as the strobe (measured: a busy-wait on EEPE returns at once), so a firmware that
 *     waits on EEPE never stalls. Here EEPE stays set for the programming time after each strobe
 *     (EEMPE then EEPE, 8.6.3), and EEPE or EERE strobes during it are ignored, as the chip
 *     neither reads nor starts a write while it programs. The byte's new value is readable through
 *     the simulator (sil_eeprom_read) from the strobe on; on the chip a reset during programming
 *     still completes the write (8.3.2), which a core reset here does too.
 *
 * Link UART bit timing (the host side at its nominal rate, the firmware at the one it programmed):
 *   the firmware's bit time is (UBRR0 + 1) x (U2X0 ? 8 : 16) cycles (22.3.1, Table 22-1), read
 *   from the registers at each byte; the host's is F_CPU / host_baud. Each byte is re-read as the
 *   receiving side samples it (22.8.1-22.8.3): the receiver sees the start edge at its first
 *   sample tick after it, counts S samples a bit (16; the AVR with U2X0: 8) and takes the
 *   majority of samples S/2, S/2 + 1, S/2 + 2 of every bit, the start bit and the stop bit
 *   included. The edge-detection delay is taken at its worst for the direction of the error (a
 *   full sample when the transmitter is the faster, none when it is the slower), and the line
 *   after the stop bit is taken as the next start bit (a back-to-back stream). A start bit read
 *   high is a spike: no byte. A stop bit read low is a framing error: the byte is delivered with
 *   FE (to the firmware: simavr's UART_INPUT_FE) and counted. The host receiver is modelled as a
 *   16-sample UART voting like the AVR's normal mode. For 8N1 this gives the datasheet's Rfast
 *   (transmitter faster by up to +4.58 % (S = 16) / +3.90 % (S = 8)) and, the slow side with a
 *   two-of-three vote, bytes intact down to -5.3 % (the datasheet's Rslow, -4.54 % / -4.00 %,
 *   also demands the first of the three samples). Noise and slow edges, which the datasheet's
 *   recommended budget (+-2.0 % / +-1.5 % per side, Tables 22-2 and 22-3) is there for, are not
 *   modelled: a 2.1 % error passes here and is caught by test_hal_avr_uart's 1 % check instead.
 *   The bytes still arrive at the firmware's byte time (simavr paces its receiver by
 *   UBRR0/U2X0), only their content follows the host's bit timing.
 *
 * Control period: writes of the throttle and left-drive compare registers (OCR3B, OCR4A low
 * bytes), which the control task makes every tick (drive.c), stamp the ticks; writes less than
 * 1 ms apart are one tick. The longest time between ticks is what a harness user reads as "worst
 * control period" (e.g. during an EEPROM save, where the watchdog is kicked per byte and its kick
 * gap shows nothing).
 */
#ifndef AGNAV_AVR_BOARD_MODEL_H
#define AGNAV_AVR_BOARD_MODEL_H

#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>

/* After avr_init(): sleep fast-forward, no level polling, write-one-to-clear TIFRn, EEPROM
 * programming time (AVR_MODEL_EEPROM_WRITE_US), control-period watch. Call again after a core
 * reset (level polling is re-armed by simavr's reset). */
void avr_model_fix(avr_t *avr);
void avr_model_hook_tifr(avr_t *avr);
void avr_model_no_level_poll(avr_t *avr);
/* UART0's simavr model, and its byte time set from UBRR0/U2X0 (call once the firmware set them). */
avr_uart_t *avr_model_uart0(avr_t *avr);
void avr_model_uart0_fix_baud(avr_t *avr, avr_uart_t *uart0);

/* ---- link UART bit timing ---------------------------------------------------------------------- */
#define AVR_MODEL_HOST_BAUD_DEFAULT 57600u /* the link's nominal rate (board.h) */
typedef struct {
    uint32_t host_baud;                  /* host side's bit rate; 0: the host follows the firmware */
    uint32_t to_host, to_host_garbled;   /* bytes the firmware sent; those the host read wrong or lost */
    uint32_t to_host_framing;            /* ... of which with a framing error */
    uint32_t to_avr, to_avr_garbled;     /* bytes the host sent; those USART0 read wrong or lost */
    uint32_t to_avr_framing;
} avr_model_link_t;

/* One 8N1 frame of `byte` sent with bit time tx_bit and read by a receiver with bit time rx_bit
 * (same unit) and `samples` samples a bit (16 or 8). Returns the byte read, with bit 8 set on a
 * framing error, or -1 when the receiver saw no start bit. */
int avr_model_uart_resample(uint8_t byte, double tx_bit, double rx_bit, unsigned samples);
/* USART0's programmed bit time in cycles and samples a bit, from UBRR0 and U2X0. */
double avr_model_uart0_bit_cycles(const avr_t *avr, unsigned *samples);
/* A byte the firmware put on TXD0, as the host reads it: -1 none, else the byte (bit 8: FE). */
int avr_model_link_to_host(avr_model_link_t *l, const avr_t *avr, uint8_t byte);
/* A byte the host puts on RXD0, as USART0 reads it: -1 none, else the UART_IRQ_INPUT value. */
int avr_model_link_to_avr(avr_model_link_t *l, const avr_t *avr, uint8_t byte);

/* ---- EEPROM programming time ------------------------------------------------------------------- */
#define AVR_MODEL_EEPROM_WRITE_US 3296u /* 26,368 RC cycles at 8 MHz (Table 8-1: 3.3 ms typ) */
/* Programming time per byte (0: simavr's own, instant); hook installed once per core. */
void avr_model_eeprom_timing(avr_t *avr, uint32_t write_us);
void avr_model_eeprom_after_reset(avr_t *avr); /* a core reset keeps a write in progress going */
uint32_t avr_model_eeprom_writes(void);        /* bytes programmed by the firmware */
uint32_t avr_model_eeprom_refused(void);       /* EEPE/EERE strobes while it was programming */

/* ---- control period ---------------------------------------------------------------------------- */
void avr_model_watch_control(avr_t *avr);
uint32_t avr_model_control_ticks(void);
/* Longest time between control ticks (us) since the last call; it starts again from 0. */
uint32_t avr_model_control_gap_max_us(void);

#endif
