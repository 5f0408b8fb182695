/*
 * USART0 rings shared by uart_avr.S (the vectors) and hal_avr.c (hal_uart_read / write).
 * Plain numbers: this header is also included by assembly.
 */
#ifndef AGNAV_UART_RING_AVR_H
#define AGNAV_UART_RING_AVR_H

#define UART_TX_SIZE 256 /* uint8_t indexes wrap by themselves (the TX vector relies on it) */
#define UART_RX_SIZE 128 /* power of two */

#endif
