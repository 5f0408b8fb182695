/*
 * ATmega2560 PORTK pin-change vector (PCINT2): the four wheel encoders of board.h
 * (encoder i: A on PK(2i), B on PK(2i+1)) decoded in one hand-written vector.
 * It only counts and timestamps, into encoder_isr_state[] with the rules of
 * firmware/lib/encoder/encoder_isr.h; everything else is the loop's.
 *
 * Cheap state in the general-purpose I/O registers (1-cycle in/out; no compiled
 * code, avr-libc routine or other ISR uses them):
 *   GPIOR1  PINK at the previous interrupt (hal_encoder_attach() seeds it)
 *   GPIOR0  scratch: t = PINK ^ (old >> 1); bit 2i = A_new ^ B_old = "raw-forward
 *           step" of encoder i (bit-addressable: sbis tests it)
 *   GPIOR2  scratch: SREG while the vector runs (never nested: I stays clear)
 * plus two pushed registers: r24 = lines that changed, r25 = working byte.
 *
 * Lines of several encoders that change within one interrupt are handled one
 * encoder after the other in the same call, highest first. Cycle counts: see
 * BENCHMARKS.md (bench/bench_firmware.py measures them under simavr).
 */
#if defined(__AVR_ATmega2560__) /* -mmcu for .S files: the platform builder's ASFLAGS */
#include <avr/io.h>

#include "../../encoder/encoder_isr.h"

#define REC encoder_isr_state
#define PINK_ADDR _SFR_MEM_ADDR(PINK)
#define TCNT5L_ADDR _SFR_MEM_ADDR(TCNT5L)
#define TCNT5H_ADDR _SFR_MEM_ADDR(TCNT5H)

.macro EPILOGUE
    pop     r25
    in      r24, _SFR_IO_ADDR(GPIOR2)
    out     _SFR_IO_ADDR(SREG), r24
    pop     r24
    reti
.endm

/* After encoder \idx: lower encoders changed too? Then dispatch again, else return. */
.macro TAIL idx
.if \idx == 0
    EPILOGUE
.else
    andi    r24, (1 << (2 * \idx)) - 1
    breq    9f
    rjmp    dispatch
9:  EPILOGUE
.endif
.endm

/* One legal step of encoder \idx: counter at offset \cnt, stamp at \stamp. Carry rule of
 * encoder_isr.h: when the low byte wraps to 0 the high byte goes up and no stamp is stored. */
.macro STEP idx, cnt, stamp
    lds     r25, REC + ENCODER_ISR_SIZE * \idx + \cnt
    subi    r25, 0xFF
    sts     REC + ENCODER_ISR_SIZE * \idx + \cnt, r25
    breq    1f
    lds     r25, TCNT5L_ADDR           /* low byte first: latches TCNT5H */
    sts     REC + ENCODER_ISR_SIZE * \idx + \stamp, r25
    lds     r25, TCNT5H_ADDR
    sts     REC + ENCODER_ISR_SIZE * \idx + \stamp + 1, r25
    TAIL    \idx
1:  lds     r25, REC + ENCODER_ISR_SIZE * \idx + \cnt + 1
    inc     r25
    sts     REC + ENCODER_ISR_SIZE * \idx + \cnt + 1, r25
    TAIL    \idx
.endm

/* Raw direction of encoder \idx's step from t (GPIOR0 bit 2 idx), then count it. */
.macro DECODE idx
    sbis    _SFR_IO_ADDR(GPIOR0), 2 * \idx
    rjmp    2f
    STEP    \idx, ENCODER_ISR_OFS_FWD, ENCODER_ISR_OFS_FWD_STAMP
2:  STEP    \idx, ENCODER_ISR_OFS_BACK, ENCODER_ISR_OFS_BACK_STAMP
.endm

/* Both lines of encoder \idx changed: an illegal jump, errors += 1. */
.macro ILLEGAL idx
    lds     r25, REC + ENCODER_ISR_SIZE * \idx + ENCODER_ISR_OFS_ERRORS
    subi    r25, 0xFF
    sts     REC + ENCODER_ISR_SIZE * \idx + ENCODER_ISR_OFS_ERRORS, r25
    brne    3f
    lds     r25, REC + ENCODER_ISR_SIZE * \idx + ENCODER_ISR_OFS_ERRORS + 1
    inc     r25
    sts     REC + ENCODER_ISR_SIZE * \idx + ENCODER_ISR_OFS_ERRORS + 1, r25
3:  TAIL    \idx
.endm

    .section .text.encoder_pcint_avr, "ax", @progbits

/* Out-of-line pieces placed before the entry so that every branch of the dispatch
 * reaches its target directly (conditional branches reach +-63 words). */
err0:
    ILLEGAL 0
err3:
    ILLEGAL 3
go_enc2:
    rjmp    enc2
lower:                                 /* r24 < 0x10: encoder 1 or 0 */
    cpi     r24, 0x04
    brsh    go_enc1
    cpi     r24, 0x01
    brlo    nothing                    /* no line changed (a glitch shorter than the entry) */
    cpi     r24, 0x03
    breq    err0
    rjmp    enc0
go_enc1:
    rjmp    enc1
nothing:
    EPILOGUE

    .global PCINT2_vect
    .type   PCINT2_vect, @function
PCINT2_vect:
    push    r24
    in      r24, _SFR_IO_ADDR(SREG)
    out     _SFR_IO_ADDR(GPIOR2), r24
    push    r25
    lds     r25, PINK_ADDR             /* r25 = new levels */
    in      r24, _SFR_IO_ADDR(GPIOR1)  /* r24 = old levels */
    out     _SFR_IO_ADDR(GPIOR1), r25
    lsr     r24                        /* old >> 1, C = old bit 0 */
    eor     r25, r24                   /* t (eor leaves C alone) */
    out     _SFR_IO_ADDR(GPIOR0), r25
    rol     r24                        /* old again */
    in      r25, _SFR_IO_ADDR(GPIOR1)
    eor     r24, r25                   /* r24 = changed lines */
/* Highest changed encoder first: r24 >= 0x40 -> 3, >= 0x10 -> 2, >= 0x04 -> 1, else 0.
 * Both bits of an encoder set (>= 0xC0, 0x30, 0x0C, == 0x03) is an illegal jump. */
dispatch:
    cpi     r24, 0x10
    brlo    lower
    cpi     r24, 0x40
    brlo    go_enc2
enc3:
    cpi     r24, 0xC0
    brsh    err3
    DECODE  3

err2:
    ILLEGAL 2
enc2:
    cpi     r24, 0x30
    brsh    err2
    DECODE  2

err1:
    ILLEGAL 1
enc1:
    cpi     r24, 0x0C
    brsh    err1
    DECODE  1

enc0:
    DECODE  0
    .size   PCINT2_vect, . - PCINT2_vect

#endif
