/* The records lib/storage writes, see storage_records.h. */
#include "storage_records.h"

#include "calib.h"
#include "params.h"
#include "signing.h"

void storage_record_slots(uint8_t record, uint16_t *main_addr, uint16_t *copy_addr, uint16_t *len)
{
    if (record == STORAGE_PARAMS) {
        *main_addr = PARAMS_EEPROM_ADDR;
        *copy_addr = PARAMS_COPY_ADDR;
        *len = params_record_bytes();
    } else if (record == STORAGE_CALIB) {
        *main_addr = CALIB_EEPROM_ADDR;
        *copy_addr = CALIB_COPY_ADDR;
        *len = CALIB_RECORD_BYTES;
    } else {
        *main_addr = SIGNING_KEY_ADDR;
        *copy_addr = SIGNING_KEY_COPY_ADDR;
        *len = SIGNING_KEY_RECORD_BYTES;
    }
}

uint8_t storage_record_byte(uint8_t record, uint16_t pos)
{
    return record == STORAGE_PARAMS ? params_record_byte(pos)
           : record == STORAGE_CALIB ? calib_record_byte(pos) : signing_key_record_byte(pos);
}
