/* Log-structured EEPROM on two flash banks: see flash_eeprom.h. */
#include "flash_eeprom.h"

#include <string.h>

static uint32_t bank_word(const fe_t *fe, uint8_t b, uint32_t off)
{
    const volatile uint8_t *p = fe->flash->bank[b] + off;
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static uint32_t records_start(const fe_t *fe) { return FE_HEADER_BYTES + (((uint32_t)fe->size + 3u) & ~3u); }

static uint8_t check_of(uint16_t addr, uint8_t value)
{
    return (uint8_t)~(uint8_t)((addr & 0xFFu) + (addr >> 8) + value);
}

static uint32_t record_word(uint16_t addr, uint8_t value)
{
    return (uint32_t)addr | ((uint32_t)value << 16) | ((uint32_t)check_of(addr, value) << 24);
}

static bool record_valid(const fe_t *fe, uint32_t w)
{
    uint16_t addr = (uint16_t)(w & 0xFFFFu);
    uint8_t value = (uint8_t)(w >> 16);
    return (uint8_t)(w >> 24) == check_of(addr, value) && addr < fe->size;
}

static bool bank_valid(const fe_t *fe, uint8_t b)
{
    return bank_word(fe, b, 0u) == FE_MAGIC && bank_word(fe, b, 4u) != 0xFFFFFFFFu;
}

/* Program and read back; a failure makes the store unusable. */
static bool program(fe_t *fe, uint8_t b, uint32_t off, uint32_t word)
{
    if (fe->flash->program_word(b, off, word) && bank_word(fe, b, off) == word) {
        return true;
    }
    fe->failures++;
    fe->usable = false;
    return false;
}

static bool erase(fe_t *fe, uint8_t b)
{
    bool ok = fe->flash->erase(b);
    for (uint32_t off = 0; ok && off < fe->flash->bank_bytes; off += 4u) {
        ok = bank_word(fe, b, off) == 0xFFFFFFFFu;
    }
    if (!ok) {
        fe->failures++;
        fe->usable = false;
    }
    return ok;
}

/* Fill bank b with the mirror as generation gen, header last; it becomes the active bank. */
static bool fill_bank(fe_t *fe, uint8_t b, uint32_t gen)
{
    if (!erase(fe, b)) {
        return false;
    }
    uint32_t n = ((uint32_t)fe->size + 3u) & ~3u;
    for (uint32_t i = 0; i < n; i += 4u) {
        uint32_t w = 0u;
        for (uint32_t k = 0; k < 4u; k++) {
            w |= (uint32_t)(i + k < fe->size ? fe->mirror[i + k] : 0xFFu) << (8u * k);
        }
        if (w != 0xFFFFFFFFu && !program(fe, b, FE_HEADER_BYTES + i, w)) {
            return false;
        }
    }
    if (!program(fe, b, 4u, gen) || !program(fe, b, 0u, FE_MAGIC)) {
        return false;
    }
    fe->active = b;
    fe->generation = gen;
    fe->next = records_start(fe);
    return true;
}

void fe_init(fe_t *fe, const fe_flash_t *flash, uint8_t *mirror, uint16_t size)
{
    fe->flash = flash;
    fe->mirror = mirror;
    fe->size = size;
    fe->failures = 0u;
    fe->usable = records_start(fe) + 4u <= flash->bank_bytes;
    memset(mirror, 0xFF, size);
    if (!fe->usable) {
        return;
    }
    bool v0 = bank_valid(fe, 0u);
    bool v1 = bank_valid(fe, 1u);
    if (!v0 && !v1) {
        (void)fill_bank(fe, 0u, 1u); /* a blank store: all 0xFF */
        return;
    }
    uint8_t b = (v0 && v1) ? (bank_word(fe, 1u, 4u) > bank_word(fe, 0u, 4u) ? 1u : 0u) : (v1 ? 1u : 0u);
    fe->active = b;
    fe->generation = bank_word(fe, b, 4u);
    for (uint16_t i = 0; i < size; i++) {
        mirror[i] = fe->flash->bank[b][FE_HEADER_BYTES + i];
    }
    uint32_t next = records_start(fe);
    for (uint32_t off = next; off + 4u <= flash->bank_bytes; off += 4u) {
        uint32_t w = bank_word(fe, b, off);
        if (w == 0xFFFFFFFFu) {
            continue;
        }
        next = off + 4u; /* after the last programmed word, torn or not */
        if (record_valid(fe, w)) {
            mirror[w & 0xFFFFu] = (uint8_t)(w >> 16);
        }
    }
    fe->next = next;
}

void fe_read(const fe_t *fe, uint16_t addr, void *dst, uint16_t len)
{
    uint8_t *d = (uint8_t *)dst;
    for (uint16_t i = 0; i < len; i++) {
        uint32_t a = (uint32_t)addr + i;
        d[i] = a < fe->size ? fe->mirror[a] : 0xFFu;
    }
}

bool fe_write(fe_t *fe, uint16_t addr, const void *src, uint16_t len)
{
    const uint8_t *s = (const uint8_t *)src;
    bool whole = true;
    for (uint16_t i = 0; i < len; i++) {
        uint32_t a = (uint32_t)addr + i;
        if (a >= fe->size) {
            whole = false;
            break;
        }
        if (fe->mirror[a] == s[i]) {
            continue;
        }
        fe->mirror[a] = s[i];
        if (!fe->usable) {
            continue;
        }
        if (fe->next + 4u > fe->flash->bank_bytes) {
            /* full: the mirror (with this byte) moves to the other bank */
            (void)fill_bank(fe, (uint8_t)(1u - fe->active), fe->generation + 1u);
            continue;
        }
        if (program(fe, fe->active, fe->next, record_word((uint16_t)a, s[i]))) {
            fe->next += 4u;
        }
    }
    return whole && fe->usable;
}

bool fe_has_room(const fe_t *fe) { return !fe->usable || fe->next + 4u <= fe->flash->bank_bytes; }

bool fe_compact_if_fuller_than(fe_t *fe, uint8_t percent)
{
    if (!fe->usable) {
        return false;
    }
    uint32_t room = fe->flash->bank_bytes - records_start(fe);
    uint32_t used = fe->next - records_start(fe);
    if (used * 100u <= room * (uint32_t)percent) {
        return false;
    }
    return fill_bank(fe, (uint8_t)(1u - fe->active), fe->generation + 1u);
}
