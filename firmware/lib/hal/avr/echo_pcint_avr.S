/*
 * ATmega2560 sonar echo vectors: PCINT0 (echo lines PB0..7, sonars 0..7) and INT0..INT3
 * (PD0..3, sonars 8..11) share this one hand-written body (board.h). It only timestamps:
 * it appends the record (PINB, PIND, TCNT5L, TCNT5H) to hal_avr_echo_q[] and advances
 * hal_avr_echo_head by 4 (a free-running byte offset, so it also counts the interrupts).
 * hal_sonar_poll() (hal_avr.c, loop context) turns the records into echo edges: which lines
 * changed, their levels, and the Timer5 stamp extended to hal_time_us().
 *
 * Three pushed registers (r24, r30, r31) and SREG on the stack; no GPIOR (those belong to the encoder vector).
 * Interrupts stay off throughout (about 55 cycles with the vector jump), so records are
 * appended whole and in order. Cycle counts: BENCHMARKS.md (bench/bench_firmware.py).
 */
#if defined(__AVR_ATmega2560__) /* -mmcu for .S files: the platform builder's ASFLAGS */
#include <avr/io.h>

#include "echo_queue_avr.h"

/* The queue lives here, not in hal_avr.c, so that unit-test builds (sim HAL) link the vector too. */
    .section .bss.hal_avr_echo, "aw", @nobits
    .global hal_avr_echo_q
    .global hal_avr_echo_head
hal_avr_echo_q:
    .skip   ECHO_Q_BYTES
hal_avr_echo_head:
    .skip   1

    .section .text.echo_pcint_avr, "ax", @progbits
    .global PCINT0_vect
    .type   PCINT0_vect, @function
    .global INT0_vect
    .global INT1_vect
    .global INT2_vect
    .global INT3_vect
PCINT0_vect:
INT0_vect:
INT1_vect:
INT2_vect:
INT3_vect:
    push    r24
    in      r24, _SFR_IO_ADDR(SREG)
    push    r24
    push    r30
    push    r31
    lds     r30, hal_avr_echo_head
    mov     r24, r30
    subi    r24, -4                    /* head += 4: the record below is complete on return */
    sts     hal_avr_echo_head, r24
    andi    r30, ECHO_Q_BYTES - 4      /* byte offset of this record */
    ldi     r31, 0
    subi    r30, lo8(-(hal_avr_echo_q))
    sbci    r31, hi8(-(hal_avr_echo_q))
    in      r24, _SFR_IO_ADDR(PINB)
    st      Z, r24
    in      r24, _SFR_IO_ADDR(PIND)
    std     Z + 1, r24
    lds     r24, _SFR_MEM_ADDR(TCNT5L) /* low byte first: latches TCNT5H */
    std     Z + 2, r24
    lds     r24, _SFR_MEM_ADDR(TCNT5H)
    std     Z + 3, r24
    pop     r31
    pop     r30
    pop     r24
    out     _SFR_IO_ADDR(SREG), r24
    pop     r24
    reti
    .size   PCINT0_vect, . - PCINT0_vect

#endif
