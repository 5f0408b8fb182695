/*
 * The firmware's records in EEPROM, written in the background so that a save never stalls the
 * control tick or the failsafe: storage_tick() (every link task, 2 ms) writes at most one changed
 * byte and returns at once while the EEPROM is still programming the previous one (hal_eeprom_busy();
 * 3.3 ms a byte on the AVR). Unchanged bytes are only read.
 *
 * Every record is written twice, into its copy slot first and then into its main slot, each pass
 * with the CRC of the bytes as they went out and each written byte read back. A power cut at any
 * byte leaves one slot whole: during the copy pass the main slot still holds the previous record,
 * during the main pass the copy holds the new one. The loaders (params_load, calib_load,
 * signing_init) take the main slot when it checks out, else the copy. A failed read-back ends the
 * record's job as failed; after a failed copy pass the main slot is left as it was.
 *
 * Record format: payload bytes, then CRC-16/CCITT-FALSE of the payload, little-endian. The payload
 * bytes are read from the owning module as the writer reaches them: a value changed during a save
 * lands in the record or not, and the CRC matches what was written either way.
 *
 * The application wires the records (storage_record_slots, storage_record_byte; lib/storage_records),
 * so this module links none of their owners. EEPROM map (addresses in the owning modules' headers):
 *   0x0040  signing key record        36 B   copy 0x00B0
 *   0x0070  signing timestamp ring    64 B   (8 slots, written by signing.c itself, a byte at a time)
 *   0x0100  calibration tables       212 B   copy 0x0400
 *   0x0200  parameters     4 + 4 n + 2 B     copy 0x0300 (n <= 62 parameters)
 */
#ifndef AGNAV_STORAGE_H
#define AGNAV_STORAGE_H

#include <stdbool.h>
#include <stdint.h>

typedef enum {
    STORAGE_PARAMS = 0,
    STORAGE_CALIB = 1,
    STORAGE_SIGNING_KEY = 2,
    STORAGE_RECORDS = 3
} storage_record_t;

#define STORAGE_BIT(record) ((uint8_t)(1u << (record)))

/* Provided by the application: record's main and copy slot addresses and its length (payload + CRC),
 * and its payload byte pos (pos < length - 2) as it is now. */
void storage_record_slots(uint8_t record, uint16_t *main_addr, uint16_t *copy_addr, uint16_t *len);
uint8_t storage_record_byte(uint8_t record, uint16_t pos);

/* Nothing queued or in progress (boot). */
void storage_init(void);
/* Queue a write of record (storage_record_t). A record already queued is written once; a record being
 * written is written again after the current pass ends, with the values as they are then. */
void storage_request(uint8_t record);
/* One step of the writer: at most one byte programmed. */
void storage_tick(void);
/* Whether record is queued or being written. */
bool storage_pending(uint8_t record);
/* Records whose write ended since the last call (STORAGE_BIT mask); *failed gets those that failed
 * (a read-back differed, the record does not fit, the flash failed). */
uint8_t storage_take_done(uint8_t *failed);
/* Whether the slot at addr holds a whole record of len bytes (payload + CRC). */
bool storage_slot_ok(uint16_t addr, uint16_t len);

#endif
