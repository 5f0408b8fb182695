/*
 * ATmega2560 USART0 vectors (the link UART, board.h), hand-written: the C versions saved
 * r0, r1, RAMPZ and r18 they did not need (65 / 63 cycles a byte; these take about 20 fewer,
 * BENCHMARKS.md). They only move one byte between UDR0 and a ring; hal_uart_read() /
 * hal_uart_write() in hal_avr.c are the loop's side. The rings live here so that unit-test
 * builds (sim HAL, no hal_avr.c) link the vectors too.
 *   RX: byte -> hal_avr_rx[head], head = (head + 1) % UART_RX_SIZE; dropped when full.
 *   TX (data register empty): hal_avr_tx[tail] -> UDR0, tail = (tail + 1) % 256; when the
 *       ring is empty, UDRIE0 off (hal_uart_write turns it on again).
 */
#if defined(__AVR_ATmega2560__) /* -mmcu for .S files: the platform builder's ASFLAGS */
#include <avr/io.h>

#include "uart_ring_avr.h"

    .section .bss.hal_avr_uart, "aw", @nobits
    .global hal_avr_tx
    .global hal_avr_rx
    .global hal_avr_tx_head
    .global hal_avr_tx_tail
    .global hal_avr_rx_head
    .global hal_avr_rx_tail
hal_avr_tx:
    .skip   UART_TX_SIZE
hal_avr_rx:
    .skip   UART_RX_SIZE
hal_avr_tx_head:
    .skip   1
hal_avr_tx_tail:
    .skip   1
hal_avr_rx_head:
    .skip   1
hal_avr_rx_tail:
    .skip   1

    .section .text.uart_avr, "ax", @progbits
    .global USART0_RX_vect
    .type   USART0_RX_vect, @function
USART0_RX_vect:
    push    r24
    in      r24, _SFR_IO_ADDR(SREG)
    push    r24
    push    r25
    push    r30
    push    r31
    lds     r25, _SFR_MEM_ADDR(UDR0)   /* read first: frees the receiver's buffer */
    lds     r30, hal_avr_rx_head
    mov     r24, r30
    inc     r24
    andi    r24, UART_RX_SIZE - 1
    lds     r31, hal_avr_rx_tail
    cp      r24, r31
    breq    1f                         /* full: drop the byte (the link's CRC notices) */
    ldi     r31, 0
    subi    r30, lo8(-(hal_avr_rx))
    sbci    r31, hi8(-(hal_avr_rx))
    st      Z, r25
    sts     hal_avr_rx_head, r24
1:  pop     r31
    pop     r30
    pop     r25
    pop     r24
    out     _SFR_IO_ADDR(SREG), r24
    pop     r24
    reti
    .size   USART0_RX_vect, . - USART0_RX_vect

    .global USART0_UDRE_vect
    .type   USART0_UDRE_vect, @function
USART0_UDRE_vect:
    push    r24
    in      r24, _SFR_IO_ADDR(SREG)
    push    r24
    push    r30
    push    r31
    lds     r30, hal_avr_tx_tail
    lds     r24, hal_avr_tx_head
    cp      r30, r24
    breq    2f
    mov     r24, r30
    inc     r24                        /* UART_TX_SIZE is 256: the byte wraps by itself */
    sts     hal_avr_tx_tail, r24
    ldi     r31, 0
    subi    r30, lo8(-(hal_avr_tx))
    sbci    r31, hi8(-(hal_avr_tx))
    ld      r24, Z
    sts     _SFR_MEM_ADDR(UDR0), r24
    rjmp    3f
2:  lds     r24, _SFR_MEM_ADDR(UCSR0B) /* empty: no more data-register-empty interrupts */
    andi    r24, ~(1 << UDRIE0) & 0xFF
    sts     _SFR_MEM_ADDR(UCSR0B), r24
3:  pop     r31
    pop     r30
    pop     r24
    out     _SFR_IO_ADDR(SREG), r24
    pop     r24
    reti
    .size   USART0_UDRE_vect, . - USART0_UDRE_vect

#endif
