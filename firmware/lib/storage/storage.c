#include "storage.h"

#include "crc16.h"
#include "hal.h"

#define NONE 0xFFu
#define BYTES_READ_PER_TICK 16u /* unchanged bytes skipped in one tick (a read is ~1 us on the AVR) */

static uint8_t s_queued;   /* STORAGE_BIT per record waiting */
static uint8_t s_done;     /* records finished since storage_take_done() */
static uint8_t s_failed;   /* ... of which failed */
static uint8_t s_record = NONE;
static uint8_t s_pass;     /* 0 copy slot, 1 main slot */
static bool s_verify;      /* the byte before s_pos was written: read it back first */
static uint8_t s_written;  /* its value */
static uint16_t s_pos;     /* next byte of the record */
static uint16_t s_crc;     /* CRC of the payload bytes before s_pos */

/* A build that wires no records (a module's unit test without the application): every write fails. */
__attribute__((weak)) void storage_record_slots(uint8_t record, uint16_t *main_addr, uint16_t *copy_addr, uint16_t *len)
{
    (void)record;
    *main_addr = *copy_addr = 0u;
    *len = 0u;
}

__attribute__((weak)) uint8_t storage_record_byte(uint8_t record, uint16_t pos)
{
    (void)record;
    (void)pos;
    return 0xFFu;
}

void storage_init(void)
{
    s_queued = s_done = s_failed = 0u;
    s_record = NONE;
}

void storage_request(uint8_t record)
{
    if (record < STORAGE_RECORDS) {
        s_queued |= STORAGE_BIT(record);
    }
}

bool storage_pending(uint8_t record)
{
    return (s_queued & STORAGE_BIT(record)) != 0u || s_record == record;
}

uint8_t storage_take_done(uint8_t *failed)
{
    uint8_t d = s_done;
    *failed = s_failed;
    s_done = 0u;
    s_failed = 0u;
    return d;
}

static void finish(bool ok)
{
    s_done |= STORAGE_BIT(s_record);
    if (!ok) {
        s_failed |= STORAGE_BIT(s_record);
    }
    s_record = NONE;
}

void storage_tick(void)
{
    if (hal_eeprom_busy()) {
        return;
    }
    if (s_record == NONE) {
        if (s_queued == 0u) {
            return;
        }
        uint8_t r = 0u;
        while ((s_queued & STORAGE_BIT(r)) == 0u) {
            r++;
        }
        s_queued = (uint8_t)(s_queued & ~STORAGE_BIT(r));
        s_record = r;
        s_pass = 0u;
        s_pos = 0u;
        s_crc = CRC16_CCITT_FALSE_INIT;
        s_verify = false;
    }
    uint16_t main_addr, copy_addr, len;
    storage_record_slots(s_record, &main_addr, &copy_addr, &len);
    uint16_t base = s_pass == 0u ? copy_addr : main_addr;
    if (len < 2u || (uint32_t)base + len > hal_eeprom_size()) {
        finish(false);
        return;
    }
    uint8_t b;
    if (s_verify) {
        s_verify = false;
        hal_eeprom_read((uint16_t)(base + s_pos - 1u), &b, 1u);
        if (b != s_written) {
            finish(false);
            return;
        }
    }
    for (uint8_t n = 0; n < BYTES_READ_PER_TICK && s_pos < len; n++) {
        uint16_t payload = (uint16_t)(len - 2u);
        if (s_pos < payload) {
            b = storage_record_byte(s_record, s_pos);
            s_crc = crc16_ccitt_false_update(s_crc, &b, 1u);
        } else {
            b = (uint8_t)(s_crc >> (s_pos == payload ? 0u : 8u));
        }
        uint16_t a = (uint16_t)(base + s_pos);
        s_pos++;
        uint8_t old;
        hal_eeprom_read(a, &old, 1u);
        if (old != b) {
            if (!hal_eeprom_write_byte(a, b)) {
                finish(false);
                return;
            }
            s_written = b;
            s_verify = true;
            return;
        }
    }
    if (s_pos < len) {
        return;
    }
    if (s_pass == 0u) {
        s_pass = 1u;
        s_pos = 0u;
        s_crc = CRC16_CCITT_FALSE_INIT;
        return;
    }
    finish(true);
}

bool storage_slot_ok(uint16_t addr, uint16_t len)
{
    if (len < 2u || (uint32_t)addr + len > hal_eeprom_size()) {
        return false;
    }
    uint16_t crc = CRC16_CCITT_FALSE_INIT;
    uint8_t b;
    uint16_t payload = (uint16_t)(len - 2u);
    for (uint16_t i = 0; i < payload; i++) {
        hal_eeprom_read((uint16_t)(addr + i), &b, 1u);
        crc = crc16_ccitt_false_update(crc, &b, 1u);
    }
    uint8_t c[2];
    hal_eeprom_read((uint16_t)(addr + payload), c, 2u);
    return (uint16_t)(c[0] | ((uint16_t)c[1] << 8)) == crc;
}
