/*
 * SHA-256 for MAVLink 2 signing, with the API of MAVLink's mavlink_sha256.h
 * (mavlink_sha256_ctx, mavlink_sha256_init / _update / _final_48), which that header lets
 * an implementation replace (HAVE_MAVLINK_SHA256). protocol/generate.py copies this file
 * next to the generated headers and agnav_mavlink.h includes it on every target.
 *
 * Why: MAVLink's C version writes each rotation as (x >> n) | (x << (32 - n)). avr-gcc has no
 * barrel shifter to map that to, so every rotate costs two shift loops of up to 31 bits:
 * 170 688 cycles (10.7 ms at 16 MHz) per 64-byte block, measured under simavr, and a signed
 * frame takes two or three blocks. Here every rotation is a whole-byte rotation (8, 16 or
 * 24 bits: register moves) followed by at most three single-bit rotations, the round
 * constants stay in flash on the AVR, and the message schedule is computed in place in a
 * 16-word ring. FIPS 180-4 test vectors and pymavlink's signatures check it
 * (firmware/test/test_signing, hil/tests/test_sil_signing.py).
 */
#ifndef AGNAV_SHA256_H
#define AGNAV_SHA256_H

#include <stdint.h>
#include <string.h>

#if defined(__AVR__) && defined(__FLASH)
#define AGNAV_SHA256_ROM __flash
#else
#define AGNAV_SHA256_ROM
#endif

typedef struct {
    union {
        unsigned char save_bytes[64];
        uint32_t save_u32[16];
    } u;
    uint32_t counter[8];
    uint32_t sz; /* bytes hashed so far */
} mavlink_sha256_ctx;

static const AGNAV_SHA256_ROM uint32_t agnav_sha256_k[64] = {
    0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
    0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
    0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
    0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
    0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
    0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
    0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
    0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2};

/* Rotations as byte moves plus single-bit steps (cheap on an 8-bit core, free elsewhere). */
static inline uint32_t agnav_rotr8(uint32_t x) { return (x >> 8) | (x << 24); }
static inline uint32_t agnav_rotr16(uint32_t x) { return (x >> 16) | (x << 16); }
static inline uint32_t agnav_rotr1(uint32_t x) { return (x >> 1) | (x << 31); }
static inline uint32_t agnav_rotl1(uint32_t x) { return (x << 1) | (x >> 31); }

/* Sigma0 = ROTR2 ^ ROTR13 ^ ROTR22; ROTR13 = ROTR16 then ROTL3, ROTR22 = ROTL8(=ROTR24) then ROTL2. */
static inline uint32_t agnav_big_sigma0(uint32_t x)
{
    uint32_t r2 = agnav_rotr1(agnav_rotr1(x));
    uint32_t r13 = agnav_rotl1(agnav_rotl1(agnav_rotl1(agnav_rotr16(x))));
    uint32_t r22 = agnav_rotl1(agnav_rotl1(agnav_rotr16(agnav_rotr8(x))));
    return r2 ^ r13 ^ r22;
}

/* Sigma1 = ROTR6 ^ ROTR11 ^ ROTR25; ROTR6 = ROTR8 then ROTL2, ROTR11 = ROTR8 then ROTR3,
 * ROTR25 = ROTR24 then ROTR1. */
static inline uint32_t agnav_big_sigma1(uint32_t x)
{
    uint32_t x8 = agnav_rotr8(x);
    uint32_t r6 = agnav_rotl1(agnav_rotl1(x8));
    uint32_t r11 = agnav_rotr1(agnav_rotr1(agnav_rotr1(x8)));
    uint32_t r25 = agnav_rotr1(agnav_rotr16(x8));
    return r6 ^ r11 ^ r25;
}

/* sigma0 = ROTR7 ^ ROTR18 ^ SHR3; ROTR7 = ROTR8 then ROTL1, ROTR18 = ROTR16 then ROTR2. */
static inline uint32_t agnav_small_sigma0(uint32_t x)
{
    uint32_t r7 = agnav_rotl1(agnav_rotr8(x));
    uint32_t r18 = agnav_rotr1(agnav_rotr1(agnav_rotr16(x)));
    return r7 ^ r18 ^ (x >> 3);
}

/* sigma1 = ROTR17 ^ ROTR19 ^ SHR10; both from ROTR16, SHR10 = SHR8 then SHR2. */
static inline uint32_t agnav_small_sigma1(uint32_t x)
{
    uint32_t r17 = agnav_rotr1(agnav_rotr16(x));
    uint32_t r19 = agnav_rotr1(agnav_rotr1(r17));
    return r17 ^ r19 ^ ((x >> 8) >> 2);
}

static inline void agnav_sha256_block(mavlink_sha256_ctx *m)
{
    uint32_t *w = m->u.save_u32;
    const unsigned char *b = m->u.save_bytes;
    for (uint8_t i = 0; i < 16u; i++, b += 4) { /* big-endian words, in place */
        uint32_t v = ((uint32_t)b[0] << 24) | ((uint32_t)b[1] << 16) | ((uint32_t)b[2] << 8) | b[3];
        w[i] = v;
    }
    uint32_t s[8];
    memcpy(s, m->counter, sizeof s);
    for (uint8_t i = 0; i < 64u; i++) {
        uint32_t data;
        if (i < 16u) {
            data = w[i];
        } else {
            data = agnav_small_sigma1(w[(i - 2u) & 15u]) + w[(i - 7u) & 15u] + agnav_small_sigma0(w[(i - 15u) & 15u]) +
                   w[i & 15u];
            w[i & 15u] = data;
        }
        uint32_t e = s[4], a = s[0];
        uint32_t t1 = s[7] + agnav_big_sigma1(e) + ((e & s[5]) ^ (~e & s[6])) + agnav_sha256_k[i] + data;
        uint32_t t2 = agnav_big_sigma0(a) + ((a & s[1]) ^ (a & s[2]) ^ (s[1] & s[2]));
        s[7] = s[6];
        s[6] = s[5];
        s[5] = e;
        s[4] = s[3] + t1;
        s[3] = s[2];
        s[2] = s[1];
        s[1] = a;
        s[0] = t1 + t2;
    }
    for (uint8_t i = 0; i < 8u; i++) {
        m->counter[i] += s[i];
    }
}

static inline void mavlink_sha256_init(mavlink_sha256_ctx *m)
{
    static const AGNAV_SHA256_ROM uint32_t H0[8] = {0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                                                   0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19};
    for (uint8_t i = 0; i < 8u; i++) {
        m->counter[i] = H0[i];
    }
    m->sz = 0;
}

static inline void mavlink_sha256_update(mavlink_sha256_ctx *m, const void *v, uint32_t len)
{
    const unsigned char *p = (const unsigned char *)v;
    uint8_t offset = (uint8_t)(m->sz % 64u);
    m->sz += len;
    while (len > 0u) {
        uint8_t room = (uint8_t)(64u - offset);
        uint8_t l = len < room ? (uint8_t)len : room;
        memcpy(m->u.save_bytes + offset, p, l);
        offset = (uint8_t)(offset + l);
        p += l;
        len -= l;
        if (offset == 64u) {
            agnav_sha256_block(m);
            offset = 0u;
        }
    }
}

/* The first 48 bits of the digest (all MAVLink signing needs). */
static inline void mavlink_sha256_final_48(mavlink_sha256_ctx *m, uint8_t result[6])
{
    uint8_t offset = (uint8_t)(m->sz % 64u);
    uint32_t bits = m->sz * 8u;
    m->u.save_bytes[offset++] = 0x80;
    if (offset > 56u) {
        memset(&m->u.save_bytes[offset], 0, 64u - offset);
        agnav_sha256_block(m);
        offset = 0u;
    }
    memset(&m->u.save_bytes[offset], 0, 60u - offset);
    m->u.save_bytes[60] = (uint8_t)(bits >> 24);
    m->u.save_bytes[61] = (uint8_t)(bits >> 16);
    m->u.save_bytes[62] = (uint8_t)(bits >> 8);
    m->u.save_bytes[63] = (uint8_t)bits;
    agnav_sha256_block(m);
    for (uint8_t i = 0; i < 6u; i++) {
        result[i] = (uint8_t)(m->counter[i / 4u] >> (24u - 8u * (i % 4u)));
    }
}

#endif
