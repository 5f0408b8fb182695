/*
 * CRC-16/CCITT-FALSE: polynomial 0x1021, initial value 0xFFFF, no input or
 * output reflection, no final XOR. Check value: the nine ASCII bytes
 * "123456789" give 0x29B1.
 *
 * Bitwise (no lookup table) to keep flash and RAM small; it is only used for
 * EEPROM records and similar short blocks, never per control tick.
 */
#ifndef AGNAV_CRC16_H
#define AGNAV_CRC16_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define CRC16_CCITT_FALSE_INIT 0xFFFFu

/* Continue a CRC over len bytes. Start with crc = CRC16_CCITT_FALSE_INIT;
 * feeding a block in pieces gives the same result as feeding it at once. */
uint16_t crc16_ccitt_false_update(uint16_t crc, const void *data, uint16_t len);

/* CRC of one whole block (init 0xFFFF). */
uint16_t crc16_ccitt_false(const void *data, uint16_t len);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_CRC16_H */
