/* ATmega2560 backend of the AgNav HAL. Pin map: board.h. Unit-test builds link the sim HAL; this
 * file is compiled there only by test/test_hal_avr_uart, test/test_hal_avr_pwm and
 * test/test_hal_avr_encoder, under other names (AGNAV_HAL_AVR_UNDER_TEST). */
#if defined(__AVR__) && (!defined(PIO_UNIT_TESTING) || defined(AGNAV_HAL_AVR_UNDER_TEST))

#include "../hal.h"
#include "board.h"
#include "../hal_clock_ms.h"

#include <avr/eeprom.h>
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <avr/wdt.h>
#include <util/delay.h>

/* ---- time: Timer5 free-running at clk/64 = 250 kHz (4 us ticks) --------
 * 4 us resolution (Arduino's micros() has the same): 0.7 mm of sonar range.
 * Converting ticks to us is then two shifts, cheap enough for interrupts. */
static volatile uint16_t s_time_overflows;
/* .noinit: written in .init3, BEFORE the C start-up clears .bss (.init4); in .bss the
 * cause always read 0 ("unknown") and a watchdog boot went unnoticed. */
static uint8_t s_reset_flags __attribute__((section(".noinit")));

/* The reset cause must be read (and MCUSR cleared) before the watchdog can
 * reset the part again; .init3 runs before main. */
void hal_avr_save_reset_cause(void) __attribute__((naked, used, section(".init3")));
void hal_avr_save_reset_cause(void)
{
    s_reset_flags = MCUSR;
    MCUSR = 0;
    wdt_disable();
}

ISR(TIMER5_OVF_vect) { s_time_overflows++; }

static uint32_t ticks_now(void)
{
    uint8_t sreg = SREG;
    cli();
    uint16_t hi = s_time_overflows;
    uint16_t lo = TCNT5;
    if ((TIFR5 & (1u << TOV5)) && lo < 0x8000u) {
        hi++; /* overflow pending, not yet serviced */
    }
    SREG = sreg;
    return ((uint32_t)hi << 16) | lo;
}

uint32_t hal_time_us(void) { return ticks_now() << 2; }
/* Milliseconds counting on across the microsecond clock's 71-minute wrap (hal_clock_ms.h). */
static hal_clock_ms_t s_clock_ms;

__attribute__((noinline)) uint32_t hal_time_ms(void) { return hal_clock_ms_update(&s_clock_ms, hal_time_us()); }

void hal_delay_us(uint16_t us)
{
    while (us-- > 0u) {
        _delay_us(1); /* cycle-counted; the 4 us timer is too coarse for a 10 us pulse */
    }
}

/* Timer5 compare A wakes the idle sleep; the ISR only has to exist. */
ISR(TIMER5_COMPA_vect) {}

void hal_idle_until(uint32_t t_us)
{
    cli();
    uint32_t now = ticks_now() << 2;
    int32_t wait_us = (int32_t)(t_us - now);
    if (wait_us <= 8) { /* nothing worth sleeping for */
        sei();
        return;
    }
    if (wait_us > 200000L) {
        wait_us = 200000L; /* within one Timer5 period (262 ms) */
    }
    OCR5A = (uint16_t)(TCNT5 + (uint16_t)((uint32_t)wait_us >> 2));
    TIFR5 = (uint8_t)(1u << OCF5A);
    TIMSK5 |= (uint8_t)(1u << OCIE5A);
    set_sleep_mode(SLEEP_MODE_IDLE); /* timers, UART and pin changes keep running */
    sleep_enable();
    sei();
    sleep_cpu(); /* the instruction after sei always runs first, so no wake-up is lost */
    sleep_disable();
    TIMSK5 &= (uint8_t)~(1u << OCIE5A);
}

hal_irq_state_t hal_irq_save(void)
{
    hal_irq_state_t s = SREG;
    cli();
    return s;
}

void hal_irq_restore(hal_irq_state_t s) { SREG = s; }

/* ---- UART0: interrupt-driven TX ring, RX ring -------------------------
 * The vectors and the rings are in uart_avr.S (hand-written, fewer saved registers). */
#include "uart_ring_avr.h"
extern uint8_t hal_avr_tx[UART_TX_SIZE];
extern uint8_t hal_avr_rx[UART_RX_SIZE];
extern volatile uint8_t hal_avr_tx_head, hal_avr_tx_tail;
extern volatile uint8_t hal_avr_rx_head, hal_avr_rx_tail;
#define s_tx hal_avr_tx
#define s_rx hal_avr_rx
#define s_tx_head hal_avr_tx_head
#define s_tx_tail hal_avr_tx_tail
#define s_rx_head hal_avr_rx_head
#define s_rx_tail hal_avr_rx_tail

/* Bit rate (ATmega2560 datasheet 2549Q, 22.3.1, Table 22-1): F_CPU / (16 (UBRR0 + 1)) with
 * U2X0 = 0, F_CPU / (8 (UBRR0 + 1)) with U2X0 = 1. d = F_CPU / (8 baud) rounded to the nearest
 * integer is the double-speed divisor with the smallest error; an even d is also the normal-speed
 * divisor d / 2 at the same rate, which keeps 16 samples a bit and the wider receiver tolerance
 * (22.8.3, Tables 22-2 and 22-3), so U2X0 is set only for an odd d. A rate that no setting meets
 * within BOARD_UART_BAUD_ERROR_PCT is refused: USART0 is left as it is (off after reset). At 16 MHz
 * that supports 9600 to 57600 baud and refuses 115200 (table and bound: docs/serial.md). The one
 * caller passes a constant, so LTO folds all of this to the four register writes. */
void hal_uart_init(uint8_t port, uint32_t baud)
{
    if (port != HAL_UART_LINK || baud == 0u || baud > F_CPU / 8u) {
        return;
    }
    uint32_t d = (F_CPU + 4u * baud) / (8u * baud);
    uint32_t clocks = 8u * d * baud; /* F_CPU x baud / actual rate */
    uint32_t off = clocks > F_CPU ? clocks - F_CPU : F_CPU - clocks;
    if (off * 100u > clocks * BOARD_UART_BAUD_ERROR_PCT || d > 8192u || ((d & 1u) != 0u && d > 4096u)) {
        return;
    }
    bool u2x = (d & 1u) != 0u;
    UBRR0 = (uint16_t)((u2x ? d : d / 2u) - 1u);
    UCSR0A = (uint8_t)(u2x ? (1u << U2X0) : 0u);
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00));
    UCSR0B = (uint8_t)((1u << RXEN0) | (1u << TXEN0) | (1u << RXCIE0));
}

uint16_t hal_uart_tx_space(uint8_t port)
{
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    return (uint16_t)(UART_TX_SIZE - 1u - (uint8_t)(s_tx_head - s_tx_tail));
}

uint16_t hal_uart_write(uint8_t port, const uint8_t *data, uint16_t len)
{
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    uint16_t n = 0;
    while (n < len && (uint8_t)(s_tx_head + 1u) != s_tx_tail) {
        s_tx[s_tx_head] = data[n++];
        s_tx_head = (uint8_t)(s_tx_head + 1u);
    }
    UCSR0B |= (uint8_t)(1u << UDRIE0);
    return n;
}

uint16_t hal_uart_read(uint8_t port, uint8_t *data, uint16_t max)
{
    if (port != HAL_UART_LINK) {
        return 0u;
    }
    uint16_t n = 0;
    while (n < max && s_rx_tail != s_rx_head) {
        data[n++] = s_rx[s_rx_tail];
        s_rx_tail = (uint8_t)((s_rx_tail + 1u) & (UART_RX_SIZE - 1u));
    }
    return n;
}

/* ---- encoders: PORTK pin-change interrupt -----------------------------
 * The vector is hand-written (encoder_pcint_avr.S): it decodes all four
 * encoders into encoder_isr_state[] (rules: encoder/encoder_isr.h) and keeps the
 * previous PINK in GPIOR1, which attach seeds here. Cycle budget and
 * measurement: BENCHMARKS.md (encoder ISR).
 * A quadrature wheel has pull-ups on A and B (open-collector outputs). A Hall wheel (hall_mask)
 * has the pull-up on A only: B keeps its pull-up off and its pin-change bit clear, so an unused B
 * line reads 0 as hal.h promises (the ATmega2560 has no pull-downs: a B line left floating must be
 * tied to GND, e.g. 10 kOhm, because the vector decodes B's level on every A edge). */
void hal_encoder_attach(uint8_t count, uint8_t hall_mask, hal_encoder_edge_fn fn)
{
    if (count > HAL_ENCODER_MAX) {
        count = HAL_ENCODER_MAX;
    }
    uint8_t mask = (uint8_t)((1u << (2u * count)) - 1u);
    uint8_t hall_b = 0u; /* the B lines (PK(2i + 1)) of Hall wheels: bit i of hall_mask to bit 2i + 1 */
    for (uint8_t b = 2u; hall_mask != 0u; hall_mask >>= 1, b = (uint8_t)(b << 2)) {
        if ((hall_mask & 1u) != 0u) {
            hall_b |= b;
        }
    }
    hall_b &= mask;
    uint8_t sreg = SREG;
    cli();
    DDRK &= (uint8_t)~mask;
    /* The levels the vector decodes from, read before the pull-ups go on: a driven line
     * (push-pull encoder, the SIL/harness rigs) reads its level either way, and simavr lets
     * a pull-up override a driven line. A floating open-collector line (Hall) can cost one
     * count or one illegal jump at boot. */
    PORTK &= (uint8_t)~hall_b;
    GPIOR1 = PINK;
    PORTK |= (uint8_t)(mask & (uint8_t)~hall_b);
    (void)fn; /* always the assembly vector on this board */
    PCMSK2 = (uint8_t)(mask & (uint8_t)~hall_b);
    PCIFR = (uint8_t)(1u << PCIF2); /* drop a change seen before GPIOR1 was seeded */
    PCICR |= (uint8_t)(1u << PCIE2);
    SREG = sreg;
}

/* Every encoder edge goes through the PORTK vector: no hardware counter to fold. */
void hal_encoder_poll(void) {}

/* The fuses select the board's 16 MHz crystal; the ATmega2560 has no clock fallback. */
bool hal_clock_from_crystal(void) { return true; }

/* ---- sonar ring: triggers on PORTA/PORTC, echoes on PCINT0 + INT0..3 ---
 * The echo vectors (echo_pcint_avr.S, one body for all five) only queue (PINB, PIND, TCNT5)
 * records; hal_sonar_poll() decodes them into edges here, in loop context, and hands
 * them to the sonar ring's hook (called directly, not through the pointer). Twelve sonars
 * give at most 8 edges per 32 ms slot and the sonar task polls every 1 ms, so 16 records
 * is ample; a stamp must be decoded within 262 ms (Timer5 period), hal.h says 100 ms. */
#include "echo_queue_avr.h"
#include "sonar_ring.h"
extern uint8_t hal_avr_echo_q[ECHO_Q_BYTES]; /* in echo_pcint_avr.S, written by the vector only */
extern volatile uint8_t hal_avr_echo_head;   /* next record's byte offset, advanced by the vector */
static uint8_t s_echo_tail;               /* next record to decode */
static uint16_t s_echo_lines;             /* echo levels after the last decoded record, bit = sonar */
static uint16_t s_echo_mask;              /* attached sonars */

void hal_sonar_poll(void)
{
    /* Head first, then the clock: every record before head is older than now, so
     * now - stamp (16-bit, < 262 ms: polled every ms) extends the stamp exactly. */
    uint8_t head = hal_avr_echo_head;
    uint32_t now_ticks = ticks_now();
    if ((uint8_t)(head - s_echo_tail) > ECHO_Q_BYTES) {
        s_echo_tail = head; /* overrun (never at 1 ms polling): drop, the next record resyncs the levels */
    }
    while (s_echo_tail != head) {
        const uint8_t *r = &hal_avr_echo_q[s_echo_tail & (ECHO_Q_BYTES - 4u)];
        s_echo_tail = (uint8_t)(s_echo_tail + 4u);
        uint16_t lines = (uint16_t)(r[0] | ((uint16_t)(r[1] & 0x0Fu) << 8)) & s_echo_mask;
        uint16_t changed = lines ^ s_echo_lines;
        if (changed == 0u) {
            continue;
        }
        s_echo_lines = lines;
        uint16_t stamp = (uint16_t)(r[2] | ((uint16_t)r[3] << 8));
        uint32_t t_us = (now_ticks - (uint16_t)((uint16_t)now_ticks - stamp)) << 2;
        for (uint8_t i = 0; changed != 0u; i++, changed >>= 1, lines >>= 1) {
            if (changed & 1u) {
                sonar_ring_isr_echo(i, (uint8_t)(lines & 1u), t_us);
            }
        }
    }
}

void hal_sonar_attach(uint8_t count, hal_echo_edge_fn fn)
{
    if (count > HAL_SONAR_MAX) {
        count = HAL_SONAR_MAX;
    }
    /* fn is always sonar_ring_isr_echo on this board (hal_sonar_poll calls it directly) */
    uint8_t low = count >= 8u ? 0xFFu : (uint8_t)((1u << count) - 1u);
    uint8_t high = count > 8u ? (uint8_t)((1u << (count - 8u)) - 1u) : 0u;
    DDRA |= low;           /* triggers 0..7 */
    DDRC |= high;          /* triggers 8..11 */
    DDRB &= (uint8_t)~low; /* echoes 0..7 */
    DDRD &= (uint8_t)~high;
    if (fn == 0) {
        low = 0u;
        high = 0u;
    }
    uint8_t sreg = SREG;
    cli();
    s_echo_mask = (uint16_t)(low | ((uint16_t)high << 8));
    s_echo_lines = (uint16_t)(PINB | ((uint16_t)(PIND & 0x0Fu) << 8)) & s_echo_mask;
    s_echo_tail = hal_avr_echo_head;
    PCMSK0 = low;
    PCICR |= (uint8_t)(1u << PCIE0);
    EICRA = 0x55u; /* INT0..3 on any edge */
    EIMSK = high;
    SREG = sreg;
}

void hal_sonar_trigger(uint8_t idx)
{
    if (idx < 8u) {
        PORTA |= (uint8_t)(1u << idx);
        hal_delay_us(10u);
        PORTA &= (uint8_t)~(1u << idx);
    } else if (idx < HAL_SONAR_MAX) {
        PORTC |= (uint8_t)(1u << (idx - 8u));
        hal_delay_us(10u);
        PORTC &= (uint8_t)~(1u << (idx - 8u));
    }
}

/* ---- actuators -------------------------------------------------------- */
void hal_servo_write_us(uint8_t channel, uint16_t pulse_us)
{
    if (pulse_us < 800u) {
        pulse_us = 800u;
    } else if (pulse_us > 2200u) {
        pulse_us = 2200u;
    }
    uint16_t ticks = (uint16_t)(pulse_us * BOARD_SERVO_TICKS_PER_US);
    if (channel == HAL_SERVO_STEER) {
        OCR3A = ticks;
    } else if (channel == HAL_SERVO_THROTTLE) {
        OCR3B = ticks;
    }
}

/* 8-bit fast PWM (Timer4 mode 5, TOP = 0xFF) cannot hold OC4x low: with OCR4x = BOTTOM the output
 * is still a one-timer-clock spike every period (ATmega2560 datasheet 2549Q, 17.9.3 Fast PWM Mode).
 * Duty 0 therefore takes the compare output off the pin (COM4x1:0 = 00, normal port operation,
 * Table 17-4) and the pin, still an output, follows its PORTH bit, which stays 0. Any other duty
 * writes OCR4x (double-buffered: takes effect at TOP) and connects OC4x non-inverting
 * (COM4x1:0 = 10: cleared on compare match, set at BOTTOM); 255 = TOP is high throughout.
 * Loop context only: TCCR4A is read-modify-written without masking interrupts (no ISR writes it). */
void hal_pwm_write_duty(uint8_t channel, uint8_t duty, bool reverse)
{
    uint8_t com;
    uint8_t dir;
    if (channel == 0u) {
        OCR4A = duty;
        com = (uint8_t)(1u << COM4A1);
        dir = (uint8_t)(1u << PH5);
    } else if (channel == 1u) {
        OCR4B = duty;
        com = (uint8_t)(1u << COM4B1);
        dir = (uint8_t)(1u << PH6);
    } else {
        return;
    }
    if (duty != 0u) {
        TCCR4A |= com;
    } else {
        TCCR4A &= (uint8_t)~com;
    }
    if (reverse) PORTH |= dir; else PORTH &= (uint8_t)~dir;
}

/* ---- EEPROM ----------------------------------------------------------- */
uint16_t hal_eeprom_size(void) { return (uint16_t)(E2END + 1u); }

void hal_eeprom_read(uint16_t addr, void *dst, uint16_t len)
{
    eeprom_read_block(dst, (const void *)(uintptr_t)addr, len);
}

bool hal_eeprom_busy(void) { return (EECR & _BV(EEPE)) != 0u; }

bool hal_eeprom_write_byte(uint16_t addr, uint8_t value)
{
    if (addr > E2END) {
        return false;
    }
    eeprom_write_byte((uint8_t *)(uintptr_t)addr, value); /* sets EEMPE/EEPE and returns: 3.3 ms in the background */
    return true;
}

void hal_eeprom_idle(void) {} /* byte-erasable EEPROM: nothing to tidy */

/* ---- watchdog --------------------------------------------------------- */
void hal_watchdog_start(uint16_t timeout_ms)
{
    uint8_t prescale = timeout_ms >= 1000u ? WDTO_1S : timeout_ms >= 500u ? WDTO_500MS
                     : timeout_ms >= 250u ? WDTO_250MS : WDTO_120MS;
    wdt_enable(prescale);
}

void hal_watchdog_kick(void) { wdt_reset(); }

hal_reset_cause_t hal_reset_cause(void)
{
    if (s_reset_flags & (1u << WDRF)) return HAL_RESET_WATCHDOG;
    if (s_reset_flags & (1u << BORF)) return HAL_RESET_BROWN_OUT;
    if (s_reset_flags & (1u << EXTRF)) return HAL_RESET_EXTERNAL;
    if (s_reset_flags & (1u << PORF)) return HAL_RESET_POWER_ON;
    return HAL_RESET_OTHER;
}

/* ---- init ------------------------------------------------------------- */
void hal_init(void)
{
    /* Timer5: normal mode, clk/64 -> 4 us ticks; overflow extends to 32 bits. */
    TCCR5A = 0;
    TCCR5B = (uint8_t)((1u << CS51) | (1u << CS50));
    TIMSK5 = (uint8_t)(1u << TOIE5);
    /* Timer3: fast PWM mode 14, TOP = ICR3 = 20 ms at 2 MHz, OC3A/OC3B non-inverting. */
    DDRE |= (uint8_t)((1u << PE3) | (1u << PE4));
    ICR3 = 40000u;
    OCR3A = 3000u;
    OCR3B = 3000u;
    TCCR3A = (uint8_t)((1u << COM3A1) | (1u << COM3B1) | (1u << WGM31));
    TCCR3B = (uint8_t)((1u << WGM33) | (1u << WGM32) | (1u << CS31));
    /* Timer4: 8-bit fast PWM (mode 5) at clk/8 for the H-bridges, 16 MHz / 8 / 256 = 7.8 kHz;
     * direction lines PH5, PH6. Duty 0 at start: OC4A/OC4B stay off the pins, which are driven
     * low by PORTH (hal_pwm_write_duty connects them for a non-zero duty). */
    PORTH &= (uint8_t)~((1u << PH3) | (1u << PH4));
    DDRH |= (uint8_t)((1u << PH3) | (1u << PH4) | (1u << PH5) | (1u << PH6));
    OCR4A = 0;
    OCR4B = 0;
    TCCR4A = (uint8_t)(1u << WGM40);
    TCCR4B = (uint8_t)((1u << WGM42) | (1u << CS41));
    sei();
}

#endif /* __AVR__ */
