#include "params.h"

#include <string.h>

#include "crc16.h"
#include "hal.h"

#define PARAMS_MAGIC 0xA61Du

static const param_def_t *s_table;
static uint16_t s_count;

void params_init(const param_def_t *table, uint16_t count)
{
    s_table = table;
    s_count = table != 0 ? count : 0u;
}

uint16_t params_count(void) { return s_count; }

int16_t params_find(const char *name)
{
    for (uint16_t i = 0; i < s_count; i++) {
        if (strncmp(s_table[i].name, name, PARAMS_NAME_LEN) == 0) {
            return (int16_t)i;
        }
    }
    return -1;
}

const param_def_t *params_def(uint16_t index) { return index < s_count ? &s_table[index] : 0; }

int32_t params_get(uint16_t index)
{
    if (index >= s_count) {
        return 0;
    }
    const param_def_t *p = &s_table[index];
    switch (p->type) {
    case PARAM_U8:
        return *(const uint8_t *)p->value;
    case PARAM_U16:
        return *(const uint16_t *)p->value;
    case PARAM_I16:
        return *(const int16_t *)p->value;
    default:
        return *(const int32_t *)p->value;
    }
}

static void store(const param_def_t *p, int32_t value)
{
    switch (p->type) {
    case PARAM_U8:
        *(uint8_t *)p->value = (uint8_t)value;
        break;
    case PARAM_U16:
        *(uint16_t *)p->value = (uint16_t)value;
        break;
    case PARAM_I16:
        *(int16_t *)p->value = (int16_t)value;
        break;
    default:
        *(int32_t *)p->value = value;
        break;
    }
}

params_result_t params_set(uint16_t index, int32_t value)
{
    if (index >= s_count) {
        return PARAMS_UNKNOWN;
    }
    const param_def_t *p = &s_table[index];
    if (value < p->min || value > p->max) {
        return PARAMS_OUT_OF_RANGE;
    }
    store(p, value);
    return PARAMS_OK;
}

void params_reset_defaults(void)
{
    for (uint16_t i = 0; i < s_count; i++) {
        store(&s_table[i], s_table[i].fallback);
    }
}

typedef struct {
    uint16_t magic;
    uint16_t count;
} params_header_t;

params_result_t params_save(uint16_t addr)
{
    params_header_t h = {PARAMS_MAGIC, s_count};
    uint16_t crc = crc16_ccitt_false_update(CRC16_CCITT_FALSE_INIT, &h, sizeof h);
    hal_eeprom_write(addr, &h, sizeof h);
    uint16_t a = (uint16_t)(addr + sizeof h);
    for (uint16_t i = 0; i < s_count; i++) {
        int32_t v = params_get(i);
        crc = crc16_ccitt_false_update(crc, &v, sizeof v);
        hal_eeprom_write(a, &v, sizeof v);
        a = (uint16_t)(a + sizeof v);
    }
    hal_eeprom_write(a, &crc, sizeof crc);
    uint16_t back = 0;
    hal_eeprom_read(a, &back, sizeof back);
    return back == crc ? PARAMS_OK : PARAMS_STORAGE;
}

params_result_t params_load(uint16_t addr)
{
    params_header_t h;
    hal_eeprom_read(addr, &h, sizeof h);
    if (h.magic != PARAMS_MAGIC || h.count != s_count) {
        params_reset_defaults();
        return PARAMS_STORAGE;
    }
    uint16_t crc = crc16_ccitt_false_update(CRC16_CCITT_FALSE_INIT, &h, sizeof h);
    uint16_t a = (uint16_t)(addr + sizeof h);
    for (uint16_t i = 0; i < s_count; i++) {
        int32_t v;
        hal_eeprom_read(a, &v, sizeof v);
        crc = crc16_ccitt_false_update(crc, &v, sizeof v);
        a = (uint16_t)(a + sizeof v);
    }
    uint16_t stored;
    hal_eeprom_read(a, &stored, sizeof stored);
    if (stored != crc) {
        params_reset_defaults();
        return PARAMS_STORAGE;
    }
    a = (uint16_t)(addr + sizeof h);
    params_result_t result = PARAMS_OK;
    for (uint16_t i = 0; i < s_count; i++) {
        int32_t v;
        hal_eeprom_read(a, &v, sizeof v);
        a = (uint16_t)(a + sizeof v);
        if (params_set(i, v) != PARAMS_OK) { /* a stored value outside today's range */
            store(&s_table[i], s_table[i].fallback);
            result = PARAMS_STORAGE;
        }
    }
    return result;
}
