/*
 * The ATmega2560 HAL back end compiled into an AVR test program under other names (avr_hal_*), so that
 * a test can drive the real register code while the modules it links see the sim HAL's hal_* calls.
 * Include this file once, before unity.h; AGNAV_HAL_AVR_UNDER_TEST opens hal_avr.c's build guard.
 */
#ifndef AGNAV_HAL_AVR_UNDER_TEST_H
#define AGNAV_HAL_AVR_UNDER_TEST_H

#define AGNAV_HAL_AVR_UNDER_TEST 1
#define hal_init avr_hal_init
#define hal_time_us avr_hal_time_us
#define hal_time_ms avr_hal_time_ms
#define hal_delay_us avr_hal_delay_us
#define hal_idle_until avr_hal_idle_until
#define hal_irq_save avr_hal_irq_save
#define hal_irq_restore avr_hal_irq_restore
#define hal_uart_init avr_hal_uart_init
#define hal_uart_write avr_hal_uart_write
#define hal_uart_read avr_hal_uart_read
#define hal_uart_tx_space avr_hal_uart_tx_space
#define hal_encoder_attach avr_hal_encoder_attach
#define hal_encoder_poll avr_hal_encoder_poll
#define hal_sonar_attach avr_hal_sonar_attach
#define hal_sonar_trigger avr_hal_sonar_trigger
#define hal_sonar_poll avr_hal_sonar_poll
#define hal_servo_write_us avr_hal_servo_write_us
#define hal_pwm_write_duty avr_hal_pwm_write_duty
#define hal_eeprom_size avr_hal_eeprom_size
#define hal_eeprom_read avr_hal_eeprom_read
#define hal_eeprom_write_byte avr_hal_eeprom_write_byte
#define hal_eeprom_busy avr_hal_eeprom_busy
#define hal_eeprom_idle avr_hal_eeprom_idle
#define hal_watchdog_start avr_hal_watchdog_start
#define hal_watchdog_kick avr_hal_watchdog_kick
#define hal_reset_cause avr_hal_reset_cause
#define hal_clock_from_crystal avr_hal_clock_from_crystal
#include "../lib/hal/avr/hal_avr.c"

#endif
