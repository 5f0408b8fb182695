/* A record written into an EEPROM slot as lib/storage writes it, for the tests of the records' owners
 * (test_calib, test_params): the payload from the owner's record-byte function, then the payload's
 * CRC-16/CCITT-FALSE, little-endian, straight into the simulated EEPROM (no storage_tick() passes).
 * Header-only (static inline): each test program is its own executable. */
#ifndef AGNAV_TEST_EEPROM_RECORD_H
#define AGNAV_TEST_EEPROM_RECORD_H

#include <stdint.h>

#include "crc16.h"
#include "sim/hal_sim.h"

/* len: the record's length, payload and CRC (CALIB_RECORD_BYTES, params_record_bytes()). */
static inline void eeprom_record_write(uint16_t addr, uint16_t len, uint8_t (*payload_byte)(uint16_t pos))
{
    uint16_t crc = CRC16_CCITT_FALSE_INIT;
    uint8_t *ee = sim_eeprom_bytes();
    for (uint16_t i = 0; i + 2u < len; i++) {
        uint8_t b = payload_byte(i);
        crc = crc16_ccitt_false_update(crc, &b, 1u);
        ee[addr + i] = b;
    }
    ee[addr + len - 2u] = (uint8_t)crc;
    ee[addr + len - 1u] = (uint8_t)(crc >> 8);
}

#endif /* AGNAV_TEST_EEPROM_RECORD_H */
