/*
 * Actuator calibration: monotone piecewise-linear maps between an actuator
 * command ("pwm") and a physical value, one table per actuator:
 *   CALIB_STEER        pwm <-> steering angle, cdeg, positive = left (REP-103)
 *   CALIB_SPEED_LEFT   pwm <-> speed, mm/s, forward positive; also the only
 *                      speed table of an Ackermann car (alias CALIB_SPEED)
 *   CALIB_SPEED_RIGHT  right-side speed table of a differential drive
 *
 * The pwm column is unit-neutral (uint16): the reference car of ref 003 uses
 * its controller's command byte (0..255); an RC servo output stage may store
 * microseconds (1000..2000); an H-bridge its 8-bit duty. Only the output
 * stage knows which; calib never writes hardware.
 *
 * Table shape: a neutral pwm (value 0) and one side per sign of the value.
 * Each side lists up to CALIB_MAX_POINTS points from the neutral outwards:
 * |pwm - neutral| and |value| both strictly increase along the list, all pos
 * points lie on one side of neutral and all neg points on the other (either
 * orientation is allowed: a servo may turn left for lower pwm). A first
 * point may sit at the neutral pwm only with value 0.
 *   dead band   pwm between neutral and the first point -> value 0
 *               (e.g. the car does not move below 43.5 cm/s)
 *   saturation  pwm beyond the last point -> the last point's value
 * Inverse lookup (value -> pwm): 0 -> neutral; |value| below the first
 * point's |value| (slower than the actuator can go) -> neutral, i.e. stop
 * rather than go faster than asked; beyond the last point -> the last pwm.
 * A speed table may leave its negative side empty (n = 0): sign-magnitude
 * drive (H-bridge duty + direction line, or a fit that covers forward only);
 * negative requests then use the positive side's magnitude and the output
 * stage sets the direction.
 *
 * Storage: one record, written by lib/storage into CALIB_COPY_ADDR and then CALIB_EEPROM_ADDR (a
 * power cut leaves one of them whole), little-endian:
 *   0  magic u16 = CALIB_MAGIC      4  length u16 = payload bytes (204)
 *   2  layout_version u8            6  payload: 3 tables x 68 bytes
 *   3  table_count u8 (3)         210  crc16 u16, CRC-16/CCITT-FALSE of bytes 0..209
 *   table: neutral u16, then pos side and neg side, each:
 *          n u8, CALIB_MAX_POINTS x {pwm u16, value i16} (unused points 0)
 * Any change to this layout must bump CALIB_LAYOUT_VERSION.
 */
#ifndef AGNAV_CALIB_H
#define AGNAV_CALIB_H

#include <stdbool.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define CALIB_MAX_POINTS 8u
#define CALIB_PWM_MAX 3000u           /* accepted pwm column range 0..3000 */
#define CALIB_ANGLE_LIMIT_CDEG 4500   /* |steering| <= 45 deg */
#define CALIB_SPEED_LIMIT_MM_S 10000  /* |speed| <= 10 m/s */

#define CALIB_EEPROM_ADDR 0x0100u     /* main slot (EEPROM map in storage.h) */
#define CALIB_COPY_ADDR 0x0400u       /* copy slot */
#define CALIB_MAGIC 0xCA1Bu
#define CALIB_LAYOUT_VERSION 1u
#define CALIB_TABLE_BYTES 68u
#define CALIB_RECORD_BYTES (6u + 3u * CALIB_TABLE_BYTES + 2u) /* 212 */

typedef enum {
    CALIB_STEER = 0,
    CALIB_SPEED_LEFT = 1,
    CALIB_SPEED_RIGHT = 2,
    CALIB_TABLE_COUNT = 3
} calib_id_t;
#define CALIB_SPEED CALIB_SPEED_LEFT

typedef struct {
    uint16_t pwm;  /* actuator command, unit-neutral */
    int16_t value; /* cdeg (steering) or mm/s (speed), signed */
} calib_point_t;

typedef struct {
    uint8_t n; /* points in use, 0 or 2..CALIB_MAX_POINTS */
    calib_point_t pt[CALIB_MAX_POINTS];
} calib_side_t;

typedef struct calib_table_s {
    uint16_t neutral_pwm; /* command giving value 0 */
    calib_side_t pos;     /* values >= 0: left turn / forward */
    calib_side_t neg;     /* values <= 0: right turn / reverse */
} calib_table_t;

/* Reason codes (0 = OK). Values are stable: the host reads them. */
typedef enum {
    CALIB_OK = 0,
    CALIB_E_BAD_ID = 1,          /* no such table */
    CALIB_E_TOO_FEW_POINTS = 2,  /* a side has 1 point, or a required side has none */
    CALIB_E_TOO_MANY_POINTS = 3, /* n > CALIB_MAX_POINTS */
    CALIB_E_NON_MONOTONE = 4,    /* |pwm - neutral| or |value| not strictly increasing */
    CALIB_E_PWM_RANGE = 5,       /* a pwm beyond CALIB_PWM_MAX */
    CALIB_E_VALUE_RANGE = 6,     /* angle beyond +-45 deg or speed beyond +-10 m/s */
    CALIB_E_WRONG_SIDE = 7,      /* point on the wrong side of neutral or with the wrong sign */
    CALIB_E_ERASED = 16,         /* load: EEPROM never written (0xFF) */
    CALIB_E_BAD_MAGIC = 17,
    CALIB_E_BAD_VERSION = 18,
    CALIB_E_BAD_LENGTH = 19,
    CALIB_E_BAD_CRC = 20,
    CALIB_E_BAD_TABLE = 21,      /* CRC fine but a stored table fails validation */
    CALIB_E_NO_SPACE = 22        /* record does not fit the EEPROM */
} calib_status_t;

/* Health bits for the host (calib_health()). */
#define CALIB_DEFAULTED 0x01u   /* active tables are the built-in defaults (nothing valid stored) */
#define CALIB_SAVE_FAILED 0x02u /* the last save did not verify */

/* Built-in defaults into the active tables; sets CALIB_DEFAULTED (nothing
 * loaded yet). No EEPROM access. */
void calib_init(void);

/* Load the stored tables from the main slot, or from the copy when the main
 * one does not check out. When neither does (erased, bad magic / version /
 * length / CRC, invalid table) the defaults become active and
 * CALIB_DEFAULTED is set; on success the flag is cleared. Returns the main
 * slot's reason (CALIB_OK when either slot loaded). */
calib_status_t calib_load(void);

/* Byte pos (pos < CALIB_RECORD_BYTES - 2) of the record of the active tables, for lib/storage, which
 * writes it (STORAGE_CALIB) and appends the CRC. */
uint8_t calib_record_byte(uint16_t pos);

/* The end of a save (lib/storage): success clears CALIB_DEFAULTED and
 * CALIB_SAVE_FAILED (storage holds the active tables); failure sets
 * CALIB_SAVE_FAILED. */
void calib_saved(bool ok);

/* CALIB_DEFAULTED | CALIB_SAVE_FAILED bits. */
uint8_t calib_health(void);

/* Reason of the last calib_load() (CALIB_OK before any load). */
calib_status_t calib_last_load_status(void);

/* Check a table for table id (the value limits depend on the id). */
calib_status_t calib_validate(uint8_t id, const calib_table_t *t);

/* Replace active table id after calib_validate(); a refused table leaves
 * the active one unchanged. Not saved until a save (storage_request(STORAGE_CALIB)). */
calib_status_t calib_set_table(uint8_t id, const calib_table_t *t);

/* Copy active table id; false for a bad id. */
bool calib_get_table(uint8_t id, calib_table_t *out);

/* Copy the built-in default of table id; false for a bad id. */
bool calib_get_default(uint8_t id, calib_table_t *out);

/* Make table id its default (the stored one is unusable, e.g. for the output stage) and say so in
 * calib_health() (CALIB_DEFAULTED) until a save. */
void calib_use_default(uint8_t id);

/* Forward lookup on the active table: pwm -> cdeg or mm/s (0 for a bad id). */
int32_t calib_value_from_pwm(uint8_t id, uint16_t pwm);

/* Inverse lookup on the active table: cdeg or mm/s -> pwm, rounded to the
 * nearest step (neutral pwm for a bad id). */
uint16_t calib_pwm_from_value(uint8_t id, int32_t value);

/* The same lookups on any (valid) table. */
int32_t calib_table_value(const calib_table_t *t, uint16_t pwm);
uint16_t calib_table_pwm(const calib_table_t *t, int32_t value);

#ifdef __cplusplus
}
#endif

#endif /* AGNAV_CALIB_H */
