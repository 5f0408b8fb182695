/*
 * simavr 1.6 model corrections for the AgNav ATmega2560 board (hil/simavr):
 *   - TIFRn writes clear only the flags written as 1 (simavr clears every pending flag, which
 *     dropped a Timer5 overflow under idle sleep: the firmware clock lost 262 ms and the watchdog
 *     reset the board);
 *   - INTn low-level pin polling off (the firmware never uses level mode; simavr polled the
 *     PE4 servo pulse every cycle, 5-7x slower);
 *   - a sleeping core is fast-forwarded instead of being paced to wall-clock time;
 *   - UART0's byte time follows UBRR0 and U2X0 as the chip does (simavr computes it before U2X0
 *     is written and runs the UART at half speed).
 */
#ifndef AGNAV_AVR_BOARD_MODEL_H
#define AGNAV_AVR_BOARD_MODEL_H

#include <simavr/avr_uart.h>
#include <simavr/sim_avr.h>

/* After avr_init(): sleep fast-forward, no level polling, write-one-to-clear TIFRn. Call again
 * after a core reset (level polling is re-armed by simavr's reset). */
void avr_model_fix(avr_t *avr);
void avr_model_hook_tifr(avr_t *avr);
void avr_model_no_level_poll(avr_t *avr);
/* UART0's simavr model, and its byte time set from UBRR0/U2X0 (call once the firmware set them). */
avr_uart_t *avr_model_uart0(avr_t *avr);
void avr_model_uart0_fix_baud(avr_t *avr, avr_uart_t *uart0);

#endif
