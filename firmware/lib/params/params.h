/*
 * Tunable parameters, exposed to ground stations through the standard MAVLink
 * parameter protocol (PARAM_REQUEST_LIST / PARAM_REQUEST_READ / PARAM_SET ->
 * PARAM_VALUE). Each module declares its rows next to its code; main.c hands
 * the whole const table to params_init(). Values live in the modules' own
 * variables, initialised to the modules' own defaults before params_load();
 * this module only reads, range-checks, stores and restores them, so every
 * default is written in one place (the module's code).
 *
 * Wire encoding: every parameter is sent as MAV_PARAM_TYPE_INT32 with the value
 * C-cast to the float field (as ArduPilot and MAVProxy do); values stay below
 * 2^24 so the cast is exact. Units are in the names (_MS, _MM, _MM_S, _CDEG).
 * Keys are append-only: never reorder or reuse a row.
 */
#ifndef AGNAV_PARAMS_H
#define AGNAV_PARAMS_H

#include <stdbool.h>
#include <stdint.h>

#include "units.h"

/* The parameter record's slots (4 B header + 4 B per parameter + CRC; map in storage.h). */
#define PARAMS_EEPROM_ADDR 0x0200u
#define PARAMS_COPY_ADDR 0x0300u

#define PARAMS_NAME_LEN 16u /* MAVLink param_id length; names shorter are NUL-terminated */

typedef enum { PARAM_U8 = 0, PARAM_U16 = 1, PARAM_I16 = 2, PARAM_I32 = 3, PARAM_I8 = 4 } param_type_t;

typedef struct {
    char name[PARAMS_NAME_LEN + 1u];
    param_type_t type;
    void *value;     /* the module's own variable */
    int32_t min;
    int32_t max;
} param_def_t;

typedef enum {
    PARAMS_OK = 0,
    PARAMS_UNKNOWN = -1,
    PARAMS_OUT_OF_RANGE = -2,
    PARAMS_STORAGE = -3,
    PARAMS_CORRUPT = -4 /* load: a record is there (not erased) but its header or CRC is bad */
} params_result_t;

/* The table lives in flash on the AVR (const RAM is scarce there): declare it
 *   static const PARAMS_ROM param_def_t TABLE[] = {...};
 * and register it (kept by reference). */
#define PARAMS_ROM UNITS_ROM
void params_init(const PARAMS_ROM param_def_t *table, uint16_t count);
uint16_t params_count(void);
/* Find by name (up to 16 chars, not necessarily NUL-terminated); -1 when unknown. */
int16_t params_find(const char *name);
/* Copy row index into *out (false when out of range). */
bool params_def(uint16_t index, param_def_t *out);
int32_t params_get(uint16_t index);

/* A counter that moves on every value stored through this module (params_set, and so params_load;
 * not the modules' own defaults): compare it with an earlier reading to know that parameters changed
 * and derived settings must be re-applied. */
uint8_t params_changes(void);
/* Range-checked set; out-of-range values are refused and the old value stays. */
params_result_t params_set(uint16_t index, int32_t value);

/* EEPROM record {magic u16, count u16, values[] i32, crc16}, written by lib/storage (a byte at a time,
 * copy slot then main slot): its length and its byte pos (pos < length - 2; the CRC is the writer's). */
uint16_t params_record_bytes(void);
uint8_t params_record_byte(uint16_t pos);

/* Load from the main slot, or from the copy when the main one does not check out (a save cut short).
 * Leaves every value as it is (the module defaults, at boot) and returns PARAMS_STORAGE when the
 * record is missing (erased) or longer than today's table, PARAMS_CORRUPT when its header or CRC is
 * bad; a stored value outside today's range is skipped (PARAMS_STORAGE) and the others are applied.
 * A record with FEWER values than the table was written before rows were appended (keys are
 * append-only): its values are applied and the newer rows keep their defaults (PARAMS_OK). */
params_result_t params_load(void);

#endif
