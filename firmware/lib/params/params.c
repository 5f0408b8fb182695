#include "params.h"

#include "crc16.h"
#include "hal.h"

#define PARAMS_MAGIC 0xA61Du

static const PARAMS_ROM param_def_t *s_table;
static uint16_t s_count;

void params_init(const PARAMS_ROM param_def_t *table, uint16_t count)
{
    s_table = table;
    s_count = table != 0 ? count : 0u;
}

uint16_t params_count(void) { return s_count; }

int16_t params_find(const char *name)
{
    for (uint16_t i = 0; i < s_count; i++) {
        const PARAMS_ROM char *n = s_table[i].name;
        uint8_t k = 0;
        while (k < PARAMS_NAME_LEN && n[k] == name[k] && name[k] != '\0') {
            k++;
        }
        if (k == PARAMS_NAME_LEN || n[k] == name[k]) {
            return (int16_t)i;
        }
    }
    return -1;
}

bool params_def(uint16_t index, param_def_t *out)
{
    if (index >= s_count) {
        return false;
    }
    const PARAMS_ROM uint8_t *src = (const PARAMS_ROM uint8_t *)&s_table[index];
    uint8_t *dst = (uint8_t *)out;
    for (uint16_t k = 0; k < sizeof *out; k++) {
        dst[k] = src[k];
    }
    return true;
}

int32_t params_get(uint16_t index)
{
    if (index >= s_count) {
        return 0;
    }
    const void *v = s_table[index].value;
    switch (s_table[index].type) {
    case PARAM_U8:
        return *(const uint8_t *)v;
    case PARAM_U16:
        return *(const uint16_t *)v;
    case PARAM_I16:
        return *(const int16_t *)v;
    case PARAM_I8:
        return *(const int8_t *)v;
    default:
        return *(const int32_t *)v;
    }
}

static uint8_t s_changes; /* stores so far (wraps): params_changes() */

uint8_t params_changes(void) { return s_changes; }

static void store(uint16_t index, int32_t value)
{
    s_changes++;
    void *v = s_table[index].value;
    switch (s_table[index].type) {
    case PARAM_U8:
        *(uint8_t *)v = (uint8_t)value;
        break;
    case PARAM_U16:
        *(uint16_t *)v = (uint16_t)value;
        break;
    case PARAM_I16:
        *(int16_t *)v = (int16_t)value;
        break;
    case PARAM_I8:
        *(int8_t *)v = (int8_t)value;
        break;
    default:
        *(int32_t *)v = value;
        break;
    }
}

params_result_t params_set(uint16_t index, int32_t value)
{
    if (index >= s_count) {
        return PARAMS_UNKNOWN;
    }
    if (value < s_table[index].min || value > s_table[index].max) {
        return PARAMS_OUT_OF_RANGE;
    }
    store(index, value);
    return PARAMS_OK;
}

typedef struct {
    uint16_t magic;
    uint16_t count;
} params_header_t;

uint16_t params_record_bytes(void) { return (uint16_t)(sizeof(params_header_t) + 4u * s_count + 2u); }

uint8_t params_record_byte(uint16_t pos)
{
    uint32_t v;
    if (pos < sizeof(params_header_t)) {
        v = pos < 2u ? PARAMS_MAGIC : s_count;
        pos &= 1u;
    } else {
        pos = (uint16_t)(pos - sizeof(params_header_t));
        v = (uint32_t)params_get((uint16_t)(pos / 4u));
        pos &= 3u;
    }
    return (uint8_t)(v >> (8u * pos));
}

static params_result_t load_at(uint16_t addr)
{
    params_header_t h;
    hal_eeprom_read(addr, &h, sizeof h);
    if (h.magic == 0xFFFFu && h.count == 0xFFFFu) {
        return PARAMS_STORAGE; /* erased: never saved */
    }
    if (h.magic != PARAMS_MAGIC || h.count == 0u || h.count > 512u) {
        return PARAMS_CORRUPT;
    }
    if (h.count > s_count) {
        return PARAMS_STORAGE; /* written by a newer firmware: do not guess */
    }
    uint16_t crc = crc16_ccitt_false_update(CRC16_CCITT_FALSE_INIT, &h, sizeof h);
    uint16_t a = (uint16_t)(addr + sizeof h);
    for (uint16_t i = 0; i < h.count; i++) {
        int32_t v;
        hal_eeprom_read(a, &v, sizeof v);
        crc = crc16_ccitt_false_update(crc, &v, sizeof v);
        a = (uint16_t)(a + sizeof v);
    }
    uint16_t stored;
    hal_eeprom_read(a, &stored, sizeof stored);
    if (stored != crc) {
        return PARAMS_CORRUPT;
    }
    a = (uint16_t)(addr + sizeof h);
    params_result_t result = PARAMS_OK;
    for (uint16_t i = 0; i < h.count; i++) {
        int32_t v;
        hal_eeprom_read(a, &v, sizeof v);
        a = (uint16_t)(a + sizeof v);
        if (params_set(i, v) != PARAMS_OK) { /* a stored value outside today's range */
            result = PARAMS_STORAGE;
        }
    }
    return result;
}

params_result_t params_load(void)
{
    params_result_t r = load_at(PARAMS_EEPROM_ADDR);
    if (r == PARAMS_OK) {
        return r;
    }
    params_result_t copy = load_at(PARAMS_COPY_ADDR);
    return copy == PARAMS_OK ? copy : r;
}
