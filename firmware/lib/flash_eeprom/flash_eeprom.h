/*
 * An EEPROM kept in two erasable flash banks, for targets without one (the STM32F405 backend of
 * the HAL). Reads come from a RAM mirror; each changed byte is appended to the active bank as a
 * 4-byte record; when the bank is full, the mirror is copied into the other bank, which then takes
 * over. Portable: the flash is reached through fe_flash_t, so the algorithm is unit-tested natively
 * against a simulated NOR flash (erase to 0xFF, programming only clears bits, power lost anywhere).
 *
 * Bank layout (little-endian 32-bit words):
 *   word 0      FE_MAGIC, programmed last when a bank is filled: a bank without it is ignored
 *   word 1      generation (the newer valid bank wins at power-up)
 *   words 2..   snapshot of the whole EEPROM (size bytes, rounded up to a word)
 *   then        records: addr (16 bits) | value << 16 | check << 24, check = ~(addr_lo + addr_hi +
 *               value); an erased word (0xFFFFFFFF) never passes the check, nor does a half-written one
 *               as a rule, so a record torn by a power cut is skipped and the next one goes after it.
 *
 * Power cut during a compaction: the new bank has no magic yet, the old one is still whole, and
 * the next compaction erases the half-filled bank first. A failed erase, program or read-back
 * marks the store unusable: the mirror keeps the values until reset (fe_t.usable says so).
 */
#ifndef AGNAV_FLASH_EEPROM_H
#define AGNAV_FLASH_EEPROM_H

#include <stdbool.h>
#include <stdint.h>

#define FE_MAGIC 0x45454741u /* "AGEE" */
#define FE_HEADER_BYTES 8u

typedef struct {
    uint32_t bank_bytes;                                          /* each bank; a multiple of 4 */
    const volatile uint8_t *bank[2];                              /* memory-mapped contents */
    bool (*erase)(uint8_t bank);                                  /* whole bank -> 0xFF */
    bool (*program_word)(uint8_t bank, uint32_t offset, uint32_t word); /* offset 4-aligned */
} fe_flash_t;

typedef struct {
    const fe_flash_t *flash;
    uint8_t *mirror;
    uint16_t size;
    uint8_t active;      /* bank in use */
    uint32_t generation; /* of the active bank */
    uint32_t next;       /* offset of the next free record slot in the active bank */
    uint16_t failures;   /* erase / program / read-back failures since init */
    bool usable;         /* false: flash failed, the mirror alone holds the data until reset */
} fe_t;

/* Bytes a bank needs for an EEPROM of size bytes and room for min_records records. */
#define FE_BANK_BYTES(size, min_records) (FE_HEADER_BYTES + (((uint32_t)(size) + 3u) & ~3u) + 4u * (min_records))

/* Load the newer valid bank into mirror (size bytes), replaying its records; formats bank 0 when
 * neither bank is valid. */
void fe_init(fe_t *fe, const fe_flash_t *flash, uint8_t *mirror, uint16_t size);

/* Bytes beyond the size read as 0xFF. */
void fe_read(const fe_t *fe, uint16_t addr, void *dst, uint16_t len);

/* Store len bytes (unchanged bytes cost nothing); false if any part beyond the size was dropped or
 * the flash failed (the mirror still holds the new values). */
bool fe_write(fe_t *fe, uint16_t addr, const void *src, uint16_t len);

/* Whether one more changed byte fits the active bank without moving to the other one (an erase); true
 * when the flash is unusable (writes then go to the mirror alone). */
bool fe_has_room(const fe_t *fe);

/* Move the mirror to the other bank now if the active one's record area is more than percent full
 * (true: moved). For a moment when the stall of an erase does no harm (the robot at rest), so that a
 * full bank seldom forces a move while it drives. */
bool fe_compact_if_fuller_than(fe_t *fe, uint8_t percent);

#endif
