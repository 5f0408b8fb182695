/*
 * Pin map of the AgNav controller on an STM32F405RG (LQFP64, the chip of the Netduino Plus 2
 * and of the board QEMU's netduinoplus2 machine models). Only this file and hal_stm32.c know
 * pin numbers.
 *
 * Board assumed: a generic STM32F405RGT6 core board that brings every LQFP64 GPIO out to pin
 * headers (8 MHz HSE crystal on PH0/PH1 unused: the clock comes from the HSI). The Netduino
 * Plus 2 itself breaks out only its Arduino-style D0..D13/A0..A5 headers (and uses several of
 * the pins below for its Ethernet, SD card, LED and button), so on that board only a subset
 * of this map is wired: the full 12-sonar, 4-encoder controller needs the core board. Every
 * pin below also exists on the LQFP100/144 parts (STM32F405VG/ZG).
 *
 * Kept free: PA9/PA10 (USART1 link), PA13/PA14 (SWD), PA11/PA12 (USB OTG FS), PB2 (BOOT1),
 * PH0/PH1 (HSE), PC14/PC15 (LSE crystal), PB3 (SWO trace), PC13 (RTC/tamper, weak driver).
 *
 *   link UART         USART1 PA9 TX / PA10 RX (AF7)
 *   time base         SysTick 1 kHz from the 168 MHz core clock + its current-value register
 *   steering servo    TIM3 CH1 = PA6 (AF2), 50 Hz, 1000-2000 us, 1 us resolution
 *   ESC / throttle    TIM3 CH2 = PA7 (AF2)
 *   H-bridge PWM      TIM4 CH1 = PB6 (AF2) left, TIM4 CH2 = PB7 (AF2) right, 20 kHz, 8-bit duty
 *   H-bridge DIR      PC12 left, PD2 right (push-pull, high = reverse)
 *   encoders          PC0..PC7 = EXTI lines 0..7: encoder i has A on PC(2i), B on PC(2i+1),
 *                     pull-ups on (open-collector Hall sensors); both edges
 *   sonar triggers    PA0..PA5 sonars 0..5, PB0 6, PB1 7, PB8 8, PA15 9, PB4 10, PB5 11
 *   sonar echoes      EXTI lines 8..15, both edges:
 *                       sonars 0..3  PB12, PB13, PB14, PB15 (lines 12..15, one line each)
 *                       sonars 4/5   PA8 / PC8   share line 8
 *                       sonars 6/7   PB9 / PC9   share line 9
 *                       sonars 8/9   PB10 / PC10 share line 10
 *                       sonars 10/11 PB11 / PC11 share line 11
 *
 * Why echoes share lines: the STM32 has 16 EXTI lines (one per pin number, each routed from
 * one port by SYSCFG_EXTICR) for 8 encoder inputs + 12 echo inputs = 20. Two sonars share a
 * line only if they are ring neighbours (idx 2k, 2k+1), which the sonar ring never fires in
 * the same group; hal_sonar_trigger() routes the line to the sonar it fires (EXTICR), so the
 * echo of the previous owner stops being seen from that moment. Rings of up to 4 sonars use
 * dedicated lines only. Encoder lines 0..4 have their own vectors (EXTI0..EXTI4); lines 5..9
 * share EXTI9_5 and 10..15 share EXTI15_10.
 *
 * Electrical: HC-SR04 echoes and many encoders are 5 V signals. Use pins that the datasheet
 * (DS8626, pin table) marks FT (5 V tolerant) for them or add a divider/level shifter; the
 * analog-capable PA0..PA7, PB0/PB1 and PC0..PC5 are not 5 V tolerant, so the encoders on
 * PC0..PC5 need 3.3 V signals (or open-collector sensors with the internal pull-up).
 */
#ifndef AGNAV_BOARD_STM32_H
#define AGNAV_BOARD_STM32_H

#define BOARD_LINK_UART_BAUD_DEFAULT 57600UL

#define BOARD_PORT_A 0u
#define BOARD_PORT_B 1u
#define BOARD_PORT_C 2u
#define BOARD_PORT_D 3u
#define BOARD_PORT_COUNT 4u /* GPIOA..GPIOD are the only ports used */

/* A pin is (port << 4) | number; the number is also its EXTI line. */
#define BOARD_PIN(port, num) ((uint8_t)(((port) << 4) | (num)))
#define BOARD_PIN_PORT(pin) ((uint8_t)((pin) >> 4))
#define BOARD_PIN_NUM(pin) ((uint8_t)((pin) & 15u))

#define BOARD_PA(n) BOARD_PIN(BOARD_PORT_A, n)
#define BOARD_PB(n) BOARD_PIN(BOARD_PORT_B, n)
#define BOARD_PC(n) BOARD_PIN(BOARD_PORT_C, n)
#define BOARD_PD(n) BOARD_PIN(BOARD_PORT_D, n)

#define BOARD_UART_TX_PIN BOARD_PA(9)
#define BOARD_UART_RX_PIN BOARD_PA(10)
#define BOARD_UART_AF 7u

#define BOARD_SERVO_PINS {BOARD_PA(6), BOARD_PA(7)} /* TIM3 CH1, CH2 */
#define BOARD_SERVO_AF 2u
#define BOARD_SERVO_PERIOD_US 20000u

#define BOARD_HBRIDGE_PWM_PINS {BOARD_PB(6), BOARD_PB(7)} /* TIM4 CH1 left, CH2 right */
#define BOARD_HBRIDGE_DIR_PINS {BOARD_PC(12), BOARD_PD(2)}
#define BOARD_HBRIDGE_AF 2u
#define BOARD_HBRIDGE_PWM_HZ 20000u

/* Encoder i: A on PC(2i) = EXTI line 2i, B on PC(2i+1) = line 2i+1. */
#define BOARD_ENCODER_PORT BOARD_PORT_C
#define BOARD_ENCODER_LINES_MASK 0x00FFu

#define BOARD_SONAR_TRIGGER_PINS                                                          \
    {BOARD_PA(0), BOARD_PA(1), BOARD_PA(2), BOARD_PA(3), BOARD_PA(4), BOARD_PA(5),         \
     BOARD_PB(0), BOARD_PB(1), BOARD_PB(8), BOARD_PA(15), BOARD_PB(4), BOARD_PB(5)}
#define BOARD_SONAR_ECHO_PINS                                                             \
    {BOARD_PB(12), BOARD_PB(13), BOARD_PB(14), BOARD_PB(15), BOARD_PA(8), BOARD_PC(8),     \
     BOARD_PB(9), BOARD_PC(9), BOARD_PB(10), BOARD_PC(10), BOARD_PB(11), BOARD_PC(11)}
#define BOARD_ECHO_LINES_MASK 0xFF00u
#define BOARD_SONAR_TRIGGER_US 10u

#endif
