/*
 * Pin map of the AgNav controller on an ATmega2560 (Arduino Mega 2560 headers).
 * Only this file and hal_avr.c know pin numbers.
 *
 *   link UART         USART0  D0 RX / D1 TX (USB or XBee, 57600 baud: UBRR0 = 34, U2X0, -0.8 %;
 *                     9600..57600 within 1 %, 115200 refused at 16 MHz, docs/serial.md)
 *   time base         Timer5, clk/64 = 4 us ticks, 16-bit overflow extended in software
 *   steering servo    Timer3 OC3A = PE3 (D5), 50 Hz, 1000-2000 us
 *   ESC / throttle    Timer3 OC3B = PE4 (D2), 50 Hz, 1000-2000 us
 *   H-bridge PWM      Timer4 OC4A = PH3 (D6) left, OC4B = PH4 (D7) right, 8-bit duty
 *   H-bridge DIR      PH5 (D8) left, PH6 (D9) right
 *   encoders          PORTK (A8..A15), PCINT2: encoder i has A on PK(2i), B on PK(2i+1);
 *                     one hand-written vector decodes all four (encoder_pcint_avr.S)
 *   GPIOR0..2         reserved for that vector: GPIOR1 = PINK at the last interrupt,
 *                     GPIOR0 / GPIOR2 scratch (no other code may use them)
 *   sonar triggers    PA0..PA7 (D22..D29) sonars 0..7, PC0..PC3 (D37..D34) sonars 8..11
 *   sonar echoes      PB0..PB7 (D53, D52, D51, D50, D10, D11, D12, D13) sonars 0..7 via PCINT0,
 *                     PD0..PD3 (D21, D20, D19, D18) sonars 8..11 via INT0..INT3 (any edge);
 *                     all five vectors are one hand-written body (echo_pcint_avr.S) that only
 *                     queues (PINB, PIND, TCNT5); hal_sonar_poll() decodes the edges in the loop
 *                     D21/D20 (PD0/PD1, sonars 8/9) are the Mega 2560's SCL/SDA and carry its
 *                     on-board 10 k pull-ups to 5 V (TWI stays off): with no sensor plugged in
 *                     these echo lines read a constant high, the other echo pins float or read
 *                     low. A fitted sensor's push-pull echo output overrides the pull-up. The
 *                     sonar ring reports either kind of missing sensor as SONAR_FAULT: no rising
 *                     edge after the trigger, a line already high at the trigger, or an echo
 *                     that does not fall within SONAR_FALL_TIMEOUT_US (sonar_ring.h)
 *   link UART vectors USART0 RX / UDRE hand-written too (uart_avr.S), rings in there
 */
#ifndef AGNAV_BOARD_AVR_H
#define AGNAV_BOARD_AVR_H

#define BOARD_LINK_UART_BAUD_DEFAULT 57600UL
/* Largest bit-rate error hal_uart_init() accepts, in percent of the nominal rate (docs/serial.md) */
#define BOARD_UART_BAUD_ERROR_PCT 1u
#define BOARD_SERVO_TICKS_PER_US 2u /* Timer3 at clk/8 */

#endif
