/*
 * The firmware's EEPROM map as the SIL fault hooks see it (sil_eeprom_record), shared by the
 * native SIL (hil/sil/sil_api.c) and the simavr one (hil/simavr/avr_sil.c). The simavr backend is
 * built without the firmware's headers, so the map is written out here; the native build includes
 * calib.h, params.h and signing.h first and checks every entry against them at compile time.
 */
#ifndef AGNAV_SIL_EEPROM_MAP_H
#define AGNAV_SIL_EEPROM_MAP_H

#include <stdint.h>

#include "sil_api.h"

#define SIL_MAP_CALIB_ADDR 0x0100u
#define SIL_MAP_CALIB_BYTES 212u
#define SIL_MAP_PARAMS_ADDR 0x0200u
#define SIL_MAP_SIGNING_KEY_ADDR 0x0040u
#define SIL_MAP_SIGNING_KEY_BYTES 36u
#define SIL_MAP_SIGNING_TS_ADDR 0x0070u
#define SIL_MAP_SIGNING_TS_BYTES 64u
#define SIL_MAP_CALIB_COPY_ADDR 0x0400u /* lib/storage writes every record's copy slot first, then its main slot */
#define SIL_MAP_PARAMS_COPY_ADDR 0x0300u
#define SIL_MAP_SIGNING_KEY_COPY_ADDR 0x00B0u
#ifndef SIL_EEPROM_PARAMS_ADDR
#define SIL_EEPROM_PARAMS_ADDR SIL_MAP_PARAMS_ADDR /* where the SIL stores parameters before boot */
#endif

#if defined(CALIB_EEPROM_ADDR) && defined(PARAMS_EEPROM_ADDR) && defined(SIGNING_KEY_ADDR)
_Static_assert(SIL_MAP_CALIB_ADDR == CALIB_EEPROM_ADDR, "calib.h moved the tables");
_Static_assert(SIL_MAP_CALIB_BYTES == CALIB_RECORD_BYTES, "calib.h changed the record size");
_Static_assert(SIL_MAP_PARAMS_ADDR == PARAMS_EEPROM_ADDR, "params.h moved the parameters");
_Static_assert(SIL_MAP_SIGNING_KEY_ADDR == SIGNING_KEY_ADDR, "signing.h moved the key");
_Static_assert(SIL_MAP_SIGNING_KEY_BYTES == SIGNING_KEY_RECORD_BYTES, "signing.h changed the key record");
_Static_assert(SIL_MAP_SIGNING_TS_ADDR == SIGNING_TS_ADDR, "signing.h moved the timestamps");
_Static_assert(SIL_MAP_SIGNING_TS_BYTES == SIGNING_TS_SLOTS * SIGNING_TS_SLOT_BYTES, "signing.h resized the timestamps");
_Static_assert(SIL_MAP_CALIB_COPY_ADDR == CALIB_COPY_ADDR, "calib.h moved the tables' copy");
_Static_assert(SIL_MAP_PARAMS_COPY_ADDR == PARAMS_COPY_ADDR, "params.h moved the parameters' copy");
_Static_assert(SIL_MAP_SIGNING_KEY_COPY_ADDR == SIGNING_KEY_COPY_ADDR, "signing.h moved the key's copy");
#endif

/* (address, length) of record `which` (SIL_REC_*); the parameter record holds a 4-byte header,
 * 4 bytes per parameter and a CRC. 0, or -1 for an unknown record. */
static inline int sil_eeprom_map(int which, uint32_t param_count, uint32_t *addr, uint32_t *len)
{
    switch (which) {
    case SIL_REC_CALIB:
        *addr = SIL_MAP_CALIB_ADDR;
        *len = SIL_MAP_CALIB_BYTES;
        return 0;
    case SIL_REC_PARAMS:
        *addr = SIL_EEPROM_PARAMS_ADDR;
        *len = 4u + 4u * param_count + 2u;
        return 0;
    case SIL_REC_SIGNING:
        *addr = SIL_MAP_SIGNING_KEY_ADDR;
        *len = SIL_MAP_SIGNING_KEY_BYTES;
        return 0;
    case SIL_REC_SIGNING_TS:
        *addr = SIL_MAP_SIGNING_TS_ADDR;
        *len = SIL_MAP_SIGNING_TS_BYTES;
        return 0;
    case SIL_REC_CALIB_COPY:
        *addr = SIL_MAP_CALIB_COPY_ADDR;
        *len = SIL_MAP_CALIB_BYTES;
        return 0;
    case SIL_REC_PARAMS_COPY:
        *addr = SIL_MAP_PARAMS_COPY_ADDR;
        *len = 4u + 4u * param_count + 2u;
        return 0;
    case SIL_REC_SIGNING_COPY:
        *addr = SIL_MAP_SIGNING_KEY_COPY_ADDR;
        *len = SIL_MAP_SIGNING_KEY_BYTES;
        return 0;
    default:
        return -1;
    }
}

#endif
