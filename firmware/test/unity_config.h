/* Unity configuration shared by every AgNav firmware test, on every target:
 * natively the output goes to stdout, on the ATmega2560 (simavr) to USART0,
 * on the STM32F405 (QEMU netduinoplus2) to USART1. See unity_output.c. */
#ifndef UNITY_CONFIG_H
#define UNITY_CONFIG_H

#ifdef __cplusplus
extern "C" {
#endif

void agnav_test_output_start(void);
void agnav_test_output_char(int c);
void agnav_test_output_flush(void);
void agnav_test_output_complete(void);

#define UNITY_OUTPUT_START() agnav_test_output_start()
#define UNITY_OUTPUT_CHAR(c) agnav_test_output_char(c)
#define UNITY_OUTPUT_FLUSH() agnav_test_output_flush()
#define UNITY_OUTPUT_COMPLETE() agnav_test_output_complete()

#if defined(__AVR__)
/* 8 KB of RAM: keep Unity lean. */
#define UNITY_EXCLUDE_DOUBLE
#define UNITY_SUPPORT_64 0
#endif

#ifdef __cplusplus
}
#endif

#endif
