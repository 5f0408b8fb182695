/*
 * The sonar echo record queue shared by echo_pcint_avr.S (writer, interrupt) and
 * hal_sonar_poll() in hal_avr.c (reader, loop). Record = 4 bytes: PINB (echoes 0..7),
 * PIND (bits 0..3: echoes 8..11), TCNT5L, TCNT5H (4 us ticks). hal_avr_echo_head is the
 * byte offset of the next record, free-running modulo 256 (64 records counted, ECHO_Q_BYTES
 * of them stored), so head - tail also tells an overrun.
 */
#ifndef AGNAV_ECHO_QUEUE_AVR_H
#define AGNAV_ECHO_QUEUE_AVR_H

#define ECHO_Q_RECORDS 16 /* power of two; 12 sonars give <= 8 edges per 32 ms slot */
#define ECHO_Q_BYTES (ECHO_Q_RECORDS * 4)

#endif
