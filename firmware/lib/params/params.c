#include "params.h"

#include "crc16.h"
#include "hal.h"

#define PARAMS_MAGIC 0xA61Du

static const PARAMS_ROM param_group_ref_t *s_groups;
static uint8_t s_group_count;
static uint16_t s_count; /* rows of all groups */

/* The row of that index, searched across the groups; 0 when there is none. */
static const PARAMS_ROM param_def_t *row(uint16_t index)
{
    for (uint8_t g = 0; g < s_group_count; g++) {
        const PARAMS_ROM param_def_t *r = s_groups[g]->rows;
        for (uint8_t k = s_groups[g]->count; k != 0u; k--, r++) {
            if (r->index == index) {
                return r;
            }
        }
    }
    return 0;
}

static void write_value(const PARAMS_ROM param_def_t *r, int32_t value)
{
    void *v = r->value;
    switch (r->type) {
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

void params_init(const PARAMS_ROM param_group_ref_t *groups, uint8_t group_count)
{
    s_groups = groups;
    s_group_count = groups != 0 ? group_count : 0u;
    s_count = 0u;
    for (uint8_t g = 0; g < s_group_count; g++) {
        const PARAMS_ROM param_def_t *r = s_groups[g]->rows;
        for (uint8_t k = s_groups[g]->count; k != 0u; k--, r++) {
            write_value(r, r->def);
            s_count++;
        }
    }
}

uint16_t params_count(void) { return s_count; }

bool params_check(void)
{
    for (uint16_t i = 0; i < s_count; i++) {
        uint16_t n = 0u;
        for (uint8_t g = 0; g < s_group_count; g++) {
            for (uint8_t k = 0; k < s_groups[g]->count; k++) {
                n = (uint16_t)(n + (s_groups[g]->rows[k].index == i ? 1u : 0u));
            }
        }
        if (n != 1u) {
            return false; /* a gap (n = 0) or a duplicate */
        }
    }
    return true;
}

int16_t params_find(const char *name)
{
    for (uint8_t g = 0; g < s_group_count; g++) {
        const PARAMS_ROM param_def_t *r = s_groups[g]->rows;
        for (uint8_t c = s_groups[g]->count; c != 0u; c--, r++) {
            const PARAMS_ROM char *n = r->name;
            uint8_t k = 0;
            while (k < PARAMS_NAME_LEN && n[k] == name[k] && name[k] != '\0') {
                k++;
            }
            if (k == PARAMS_NAME_LEN || n[k] == name[k]) {
                return (int16_t)r->index;
            }
        }
    }
    return -1;
}

bool params_def(uint16_t index, param_def_t *out)
{
    const PARAMS_ROM param_def_t *r = row(index);
    if (r == 0) {
        return false;
    }
    *out = *r;
    return true;
}

int32_t params_get(uint16_t index)
{
    const PARAMS_ROM param_def_t *r = row(index);
    if (r == 0) {
        return 0;
    }
    const void *v = r->value;
    switch (r->type) {
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

params_result_t params_set(uint16_t index, int32_t value)
{
    const PARAMS_ROM param_def_t *r = row(index);
    if (r == 0) {
        return PARAMS_UNKNOWN;
    }
    if (value < r->min || value > r->max) {
        return PARAMS_OUT_OF_RANGE;
    }
    s_changes++;
    write_value(r, value);
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
