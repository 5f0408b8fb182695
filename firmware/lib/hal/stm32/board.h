/*
 * Pin map of the AgNav controller on the Olimex STM32-H405: STM32F405RGT6 (LQFP64), open
 * hardware, every GPIO on its two 26-pin headers (EXT1, EXT2), 8 MHz HSE crystal, 32.768 kHz
 * LSE crystal, 20-pin JTAG/SWD connector, USB device port. Chosen because it is a commonly sold
 * F405 board that adds almost nothing to the chip's pins: what it does use is kept free below.
 * Only this file and hal_stm32.c know pin numbers. Wiring table and flashing: docs/stm32.md.
 *
 * Kept free (board parts, from the board's schematic facts as NuttX's and Zephyr's board files
 * for it state them, and the chip's dedicated pins):
 *   PA0            user button BUT (WKUP)
 *   PC12           status LED (green, on when low)
 *   PA11 / PA12    USB OTG FS D- / D+ (also the ROM bootloader's DFU port)
 *   PC4            USB VBUS sense (through a divider)
 *   PC11           "USB DISC", the USB disconnect line (EXT1 header label)
 *   PH0 / PH1      8 MHz HSE crystal;  PC14 / PC15  32.768 kHz LSE crystal
 *   PA13 / PA14    SWDIO / SWCLK;  PA15, PB3, PB4  JTAG TDI, TDO/SWO, nTRST on the same connector
 *   PB2            BOOT1
 *   PC13           RTC / tamper pin: supplied through the backup power switch, 3 mA, 2 MHz
 *                  (DS8626, output voltage characteristics note), not a general-purpose output
 *
 *   link UART         USART1 PA9 TX / PA10 RX (AF7), EXT header; also the ROM bootloader's USART
 *   clock             HSE 8 MHz -> PLL -> 168 MHz (hal_stm32.c clock_init; HSI fallback)
 *   time base         SysTick 1 kHz from the 168 MHz core clock + its current-value register
 *   encoders          timer encoder mode (x4) on TIM2, TIM3, TIM4, TIM8 (A/B = CH1/CH2 inputs):
 *                       encoder 0  TIM2  A PA1 (CH2)  B PA5 (CH1)  AF1
 *                       encoder 1  TIM3  A PB5 (CH2)  B PA6 (CH1)  AF2
 *                       encoder 2  TIM4  A PB6 (CH1)  B PB7 (CH2)  AF2
 *                       encoder 3  TIM8  A PC7 (CH2)  B PC6 (CH1)  AF3
 *                     a Hall (single-channel) wheel uses its A pin as a GPIO input on EXTI
 *                     line 1, 5, 6, 7 (A's pin numbers), both edges; B unused
 *   steering servo    TIM9 CH1 = PA2 (AF3), 50 Hz, 1 us resolution
 *   ESC / throttle    TIM9 CH2 = PA3 (AF3)
 *   H-bridge PWM      TIM10 CH1 = PB8 (AF3) left, TIM11 CH1 = PB9 (AF3) right, 20 kHz, 8-bit duty
 *   H-bridge DIR      PA7 left, PB1 right (push-pull, high = reverse)
 *   sonar triggers    6 outputs: PC0 sonar 0, PC1 sonar 3, PC2 sonar 6, PC5 sonar 9,
 *                     PA8 sonars 1, 4, 7, 10 together, PC10 sonars 2, 5, 8, 11 together
 *   sonar echoes      one EXTI line each, both edges:
 *                       sonars 0..3   PB12, PB13, PB14, PB15  (lines 12..15)
 *                       sonars 4, 5   PB11, PB10              (lines 11, 10)
 *                       sonars 6, 7   PC9, PC8                (lines 9, 8)
 *                       sonars 8..11  PD2, PC3, PB0, PA4      (lines 2, 3, 0, 4)
 *
 * Why these timers: encoder mode needs a timer's CH1 and CH2 (TIM1..5, TIM8 have it); on this
 * board TIM5's CH1 is only on PA0 (the button) and TIM1's CH2 only on PA9 (the link), which
 * leaves TIM2, TIM3, TIM4, TIM8. The servo and H-bridge PWM go to timers without encoder mode:
 * TIM9 (two channels, one 50 Hz period) and the one-channel TIM10 / TIM11 (one 20 kHz period
 * each). TIM12's pins PB14/PB15 carry echoes instead: only they give EXTI lines 14 and 15.
 *
 * Why sonars share triggers: 32 pins are left for 8 encoder inputs, 4 drive outputs, 2 DIR lines,
 * 12 echoes and the triggers. The sonar ring fires {1,4,7,10} together and {2,5,8,11} together
 * for every ring size (group = i % 3; the only sensor a ring moves to another group is its last
 * one when that is 3, 6 or 9, which keep their own pins; sonar_ring.h), so each of those sets
 * shares one trigger pin: hal_sonar_trigger() pulses a shared pin for the first sonar of the set
 * and not again within BOARD_SONAR_TRIGGER_SHARED_US. A sonar on a shared pin fires with its set
 * even if the ring's cross-talk guard held it back (the guard only acts on a wrong schedule).
 *
 * Why A is on CH2 for three encoders: a Hall wheel needs A on an EXTI line no echo uses, and the
 * CH1 pins of TIM3, TIM4 and TIM8 (PA6, PB6, PC6) all have pin number 6. hal_encoder_poll()
 * counts forward when A leads B whichever channel A is on (BOARD_ENCODER_A_ON_CH2).
 *
 * Electrical: HC-SR04 echoes and many encoders are 5 V signals; every pin used here is 5 V
 * tolerant (FT in DS8626 Table 7, pin and ball definitions; not in analog mode) except PA4 and
 * PA5, the DAC pins (TTa, 3.3 V only): sonar 11's echo (PA4) needs a divider or a 3.3 V sensor,
 * and encoder 0's B (PA5) a 3.3 V or open-collector signal (internal pull-up). 5 V Hall sensors
 * with open-collector outputs work on every encoder input with the internal pull-up.
 */
#ifndef AGNAV_BOARD_STM32_H
#define AGNAV_BOARD_STM32_H

#define BOARD_NAME "Olimex STM32-H405"
#define BOARD_HSE_HZ 8000000u /* the board's crystal */
#define BOARD_LINK_UART_BAUD_DEFAULT 57600UL

#define BOARD_PORT_A 0u
#define BOARD_PORT_B 1u
#define BOARD_PORT_C 2u
#define BOARD_PORT_D 3u
#define BOARD_PORT_COUNT 4u /* GPIOA..GPIOD are the only ports used (GPIOH: the crystal) */

/* A pin is (port << 4) | number; the number is also its EXTI line. */
#define BOARD_PIN(port, num) ((uint8_t)(((port) << 4) | (num)))
#define BOARD_PIN_PORT(pin) ((uint8_t)((pin) >> 4))
#define BOARD_PIN_NUM(pin) ((uint8_t)((pin) & 15u))

#define BOARD_PA(n) BOARD_PIN(BOARD_PORT_A, n)
#define BOARD_PB(n) BOARD_PIN(BOARD_PORT_B, n)
#define BOARD_PC(n) BOARD_PIN(BOARD_PORT_C, n)
#define BOARD_PD(n) BOARD_PIN(BOARD_PORT_D, n)

/* Pins of the board itself and the chip's dedicated ones: nothing of the map may use them. */
#define BOARD_RESERVED_PINS                                                                    \
    {BOARD_PA(0), BOARD_PC(12), BOARD_PA(11), BOARD_PA(12), BOARD_PC(4), BOARD_PC(11),          \
     BOARD_PC(14), BOARD_PC(15), BOARD_PA(13), BOARD_PA(14), BOARD_PA(15), BOARD_PB(3),          \
     BOARD_PB(4), BOARD_PB(2), BOARD_PC(13)}

#define BOARD_UART_TX_PIN BOARD_PA(9)
#define BOARD_UART_RX_PIN BOARD_PA(10)
#define BOARD_UART_AF 7u

/* Timers by register base (RM0090 2.3, memory map). */
#define BOARD_TIM2_BASE 0x40000000u
#define BOARD_TIM3_BASE 0x40000400u
#define BOARD_TIM4_BASE 0x40000800u
#define BOARD_TIM8_BASE 0x40010400u
#define BOARD_TIM9_BASE 0x40014000u
#define BOARD_TIM10_BASE 0x40014400u
#define BOARD_TIM11_BASE 0x40014800u

/* Encoder i: timer, pins, alternate function; bit i of A_ON_CH2: A is the timer's TI2. */
#define BOARD_ENCODER_TIMERS {BOARD_TIM2_BASE, BOARD_TIM3_BASE, BOARD_TIM4_BASE, BOARD_TIM8_BASE}
#define BOARD_ENCODER_A_PINS {BOARD_PA(1), BOARD_PB(5), BOARD_PB(6), BOARD_PC(7)}
#define BOARD_ENCODER_B_PINS {BOARD_PA(5), BOARD_PA(6), BOARD_PB(7), BOARD_PC(6)}
#define BOARD_ENCODER_AF {1u, 2u, 2u, 3u}
#define BOARD_ENCODER_A_ON_CH2 0x0Bu /* encoders 0, 1, 3 */

#define BOARD_SERVO_PINS {BOARD_PA(2), BOARD_PA(3)} /* TIM9 CH1, CH2 */
#define BOARD_SERVO_AF 3u
#define BOARD_SERVO_PERIOD_US 20000u

#define BOARD_HBRIDGE_PWM_PINS {BOARD_PB(8), BOARD_PB(9)} /* TIM10 CH1 left, TIM11 CH1 right */
#define BOARD_HBRIDGE_TIMERS {BOARD_TIM10_BASE, BOARD_TIM11_BASE}
#define BOARD_HBRIDGE_DIR_PINS {BOARD_PA(7), BOARD_PB(1)}
#define BOARD_HBRIDGE_AF 3u
#define BOARD_HBRIDGE_PWM_HZ 20000u

/* Trigger outputs, and which of them each sonar fires. */
#define BOARD_SONAR_TRIGGER_COUNT 6u
#define BOARD_SONAR_TRIGGER_PINS {BOARD_PC(0), BOARD_PC(1), BOARD_PC(2), BOARD_PC(5), BOARD_PA(8), BOARD_PC(10)}
#define BOARD_SONAR_TRIGGER_OF {0u, 4u, 5u, 1u, 4u, 5u, 2u, 4u, 5u, 3u, 4u, 5u}
/* A shared trigger pin pulsed less than this ago is not pulsed again: the ring fires a group's
 * members back to back (well under 1 ms) and the same group again >= 2 slots (64 ms) later. */
#define BOARD_SONAR_TRIGGER_SHARED_US 1000u
#define BOARD_SONAR_ECHO_PINS                                                             \
    {BOARD_PB(12), BOARD_PB(13), BOARD_PB(14), BOARD_PB(15), BOARD_PB(11), BOARD_PB(10),   \
     BOARD_PC(9), BOARD_PC(8), BOARD_PD(2), BOARD_PC(3), BOARD_PB(0), BOARD_PA(4)}
#define BOARD_ECHO_LINES_MASK 0xFF1Du /* lines 0, 2, 3, 4, 8..15 */
#define BOARD_HALL_LINES_MASK 0x00E2u /* lines 1, 5, 6, 7: the encoders' A pins */
#define BOARD_SONAR_TRIGGER_US 10u

#endif
