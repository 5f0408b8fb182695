/*
 * Tunable parameters, exposed to ground stations through the standard MAVLink
 * parameter protocol (PARAM_REQUEST_LIST / PARAM_REQUEST_READ / PARAM_SET ->
 * PARAM_VALUE), declared per module like ArduPilot's AP_Param groups.
 *
 * Each module declares its rows beside its code (lib/<module>/<module>_params.c):
 * name (unit in the name), type, its own variable, min, max, default and the
 * row's key, a stable index. main.c lists the groups and hands the list to
 * params_init(), which writes every row's default into its variable before
 * params_load(); this module then reads, range-checks, stores and restores the
 * values. Rows are found by their index across the groups (no table in RAM).
 *
 * The index is the row's PARAM_VALUE param_index and its slot in the EEPROM
 * record: the indices of all groups together are 0..N-1, each once
 * (params_check()). Keys are append-only: a new row takes index N, a row is
 * never renumbered or reused.
 *
 * Wire encoding: every parameter is sent as MAV_PARAM_TYPE_INT32 with the value
 * C-cast to the float field (as ArduPilot and MAVProxy do); values stay below
 * 2^24 so the cast is exact. Units are in the names (_MS, _MM, _MM_S, _CDEG).
 */
#ifndef AGNAV_PARAMS_H
#define AGNAV_PARAMS_H

#include <stdbool.h>
#include <stdint.h>

#include "units.h"

/* The parameter record's slots (4 B header + 4 B per parameter + CRC; map in storage.h). */
#define PARAMS_EEPROM_ADDR 0x0200u
#define PARAMS_COPY_ADDR 0x0300u

#define PARAMS_ROM UNITS_ROM /* rows and groups: in flash on the AVR */
#define PARAMS_NAME_LEN 16u /* MAVLink param_id length; names shorter are NUL-terminated */

typedef enum { PARAM_U8 = 0, PARAM_U16 = 1, PARAM_I16 = 2, PARAM_I32 = 3, PARAM_I8 = 4 } param_type_t;

/* One parameter. On the AVR a row is 33 bytes in flash, in this order (hil/simavr/avr_sil.c reads it). */
typedef struct {
    char name[PARAMS_NAME_LEN + 1u];
    uint8_t index;   /* the key: PARAM_VALUE param_index and slot in the EEPROM record */
    uint8_t type;    /* param_type_t */
    void *value;     /* the module's own variable */
    int32_t min;
    int32_t max;
    int32_t def;     /* the default, written by params_init() */
} param_def_t;

/* The rows one module declares (ArduPilot: a parameter group). */
typedef struct {
    const PARAMS_ROM param_def_t *rows;
    uint8_t count;
} param_group_t;

/* A group of a module's row table: PARAM_GROUP(ROWS) in the module's own file. */
#define PARAM_GROUP(rows) {(rows), (uint8_t)(sizeof(rows) / sizeof((rows)[0]))}

typedef enum {
    PARAMS_OK = 0,
    PARAMS_UNKNOWN = -1,
    PARAMS_OUT_OF_RANGE = -2,
    PARAMS_STORAGE = -3,
    PARAMS_CORRUPT = -4 /* load: a record is there (not erased) but its header or CRC is bad */
} params_result_t;

/* Rows and groups live in flash on the AVR (const RAM is scarce there): a module declares
 *   static const PARAMS_ROM param_def_t ROWS[] = {{"NAME", index, PARAM_U16, &var, min, max, def}, ...};
 *   const PARAMS_ROM param_group_t MODULE_PARAM_GROUP = PARAM_GROUP(ROWS);
 * and main.c lists the groups (kept by reference):
 *   static const PARAMS_ROM param_group_ref_t PARAM_GROUPS[] = {&MODULE_PARAM_GROUP, ...}; */
typedef const PARAMS_ROM param_group_t *param_group_ref_t;

/* Register the groups and write every row's default into its variable (not a change:
 * params_changes() stays). */
void params_init(const PARAMS_ROM param_group_ref_t *groups, uint8_t group_count);
/* Rows of all groups: the indices run 0..params_count()-1. */
uint16_t params_count(void);
/* True when every index 0..params_count()-1 belongs to exactly one row (no gap, no duplicate). */
bool params_check(void);
/* Find by name (up to 16 chars, not necessarily NUL-terminated): its index, -1 when unknown. */
int16_t params_find(const char *name);
/* Copy the row of that index into *out (false when there is none). */
bool params_def(uint16_t index, param_def_t *out);
int32_t params_get(uint16_t index);

/* A counter that moves on every value stored through this module (params_set, and so params_load;
 * not the defaults params_init() writes): compare it with an earlier reading to know that parameters changed
 * and derived settings must be re-applied. */
uint8_t params_changes(void);
/* Range-checked set; out-of-range values are refused and the old value stays. */
params_result_t params_set(uint16_t index, int32_t value);

/* EEPROM record {magic u16, count u16, values[] i32, crc16}, written by lib/storage (a byte at a time,
 * copy slot then main slot): its length and its byte pos (pos < length - 2; the CRC is the writer's). */
uint16_t params_record_bytes(void);
uint8_t params_record_byte(uint16_t pos);

/* Load from the main slot, or from the copy when the main one does not check out (a save cut short).
 * Leaves every value as it is (the defaults, at boot) and returns PARAMS_STORAGE when the
 * record is missing (erased) or longer than today's rows, PARAMS_CORRUPT when its header or CRC is
 * bad; a stored value outside today's range is skipped (PARAMS_STORAGE) and the others are applied.
 * A record with FEWER values than there are rows was written before rows were appended (keys are
 * append-only): its values are applied and the newer rows keep their defaults (PARAMS_OK). */
params_result_t params_load(void);

#endif
