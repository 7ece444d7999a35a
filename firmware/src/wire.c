/* Little-endian field access and f32/f64 bit conversions, integer arithmetic only (no FPU, no double). */
#include "wire.h"

#include <string.h>

void wire_put_u16(uint8_t *p, uint16_t v) {
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
}

void wire_put_u32(uint8_t *p, uint32_t v) {
    for (int i = 0; i < 4; i++) { p[i] = (uint8_t)(v >> (8 * i)); }
}

void wire_put_u64(uint8_t *p, uint64_t v) {
    for (int i = 0; i < 8; i++) { p[i] = (uint8_t)(v >> (8 * i)); }
}

void wire_put_f32(uint8_t *p, float v) { wire_put_u32(p, f32_bits(v)); }

uint16_t wire_get_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }

uint32_t wire_get_u32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

uint64_t wire_get_u64(const uint8_t *p) {
    return (uint64_t)wire_get_u32(p) | ((uint64_t)wire_get_u32(p + 4) << 32);
}

float wire_get_f32(const uint8_t *p) { return f32_from_bits(wire_get_u32(p)); }

const uint8_t *wire_zero_extend(uint8_t *buf, size_t size, const uint8_t *payload, size_t n) {
    if (n >= size) { return payload; }
    memset(buf, 0, size);
    if (n > 0u) { memcpy(buf, payload, n); }
    return buf;
}

uint32_t f32_bits(float v) {
    uint32_t bits;
    memcpy(&bits, &v, sizeof bits);
    return bits;
}

float f32_from_bits(uint32_t bits) {
    float v;
    memcpy(&v, &bits, sizeof v);
    return v;
}

#define F64_EXP_MASK 0x7FFu
#define F64_FRAC_BITS 52
#define F64_BIAS 1023
#define F32_BIAS 127

uint64_t f64_bits_from_f32(float v) {
    uint32_t b = f32_bits(v);
    uint64_t sign = (uint64_t)(b >> 31) << 63;
    int32_t exp = (int32_t)((b >> 23) & 0xFFu);
    uint64_t frac = b & 0x7FFFFFu;
    if (exp == 0xFF) {  /* inf / nan */
        return sign | ((uint64_t)F64_EXP_MASK << F64_FRAC_BITS) | (frac << 29);
    }
    if (exp == 0) {
        if (frac == 0u) { return sign; }
        exp = 1;  /* subnormal: normalise */
        while ((frac & 0x800000u) == 0u) { frac <<= 1; exp--; }
        frac &= 0x7FFFFFu;
    }
    return sign | ((uint64_t)(exp - F32_BIAS + F64_BIAS) << F64_FRAC_BITS) | (frac << 29);
}

bool f64_bits_finite(uint64_t bits) { return ((bits >> F64_FRAC_BITS) & F64_EXP_MASK) != F64_EXP_MASK; }

float f64_bits_to_f32(uint64_t bits) {
    uint32_t sign = (uint32_t)(bits >> 63) << 31;
    int32_t exp = (int32_t)((bits >> F64_FRAC_BITS) & F64_EXP_MASK);
    uint64_t frac = bits & ((1ull << F64_FRAC_BITS) - 1u);
    if (exp == (int32_t)F64_EXP_MASK) { return f32_from_bits(sign | 0x7F800000u | (frac ? 0x400000u : 0u)); }
    if (exp == 0 && frac == 0u) { return f32_from_bits(sign); }
    /* mantissa with its hidden bit, value = m * 2^(e - 52) */
    uint64_t m = exp ? (frac | (1ull << F64_FRAC_BITS)) : frac;
    int32_t e = (exp ? exp : 1) - F64_BIAS;
    int32_t e32 = e + F32_BIAS;  /* biased f32 exponent if normal */
    int32_t shift = 29;          /* 52 - 23 fraction bits dropped */
    if (e32 <= 0) { shift += 1 - e32; e32 = 0; }  /* subnormal f32 */
    if (shift > 63) { return f32_from_bits(sign); }
    uint64_t kept = m >> shift;
    uint64_t rest = m & ((1ull << shift) - 1u);
    uint64_t half = 1ull << (shift - 1);
    if (rest > half || (rest == half && (kept & 1u))) { kept++; }
    uint32_t out;
    if (e32 == 0) {
        out = (uint32_t)kept;  /* may round up into the smallest normal: the bits still read right */
    } else {
        if (kept >> 24) { kept >>= 1; e32++; }
        if (e32 >= 0xFF) { return f32_from_bits(sign | 0x7F800000u); }
        out = ((uint32_t)e32 << 23) | ((uint32_t)kept & 0x7FFFFFu);
    }
    return f32_from_bits(sign | out);
}

bool f64_bits_to_integer(uint64_t bits, int64_t *out) {
    if (!f64_bits_finite(bits)) { return false; }
    bool negative = (bits >> 63) != 0u;
    int32_t exp = (int32_t)((bits >> F64_FRAC_BITS) & F64_EXP_MASK);
    uint64_t frac = bits & ((1ull << F64_FRAC_BITS) - 1u);
    if (exp == 0) {
        if (frac != 0u) { return false; }
        *out = 0;
        return true;
    }
    int32_t e = exp - F64_BIAS;
    if (e < 0 || e > 62) { return false; }
    uint64_t m = frac | (1ull << F64_FRAC_BITS);
    uint64_t value;
    if (e >= F64_FRAC_BITS) {
        value = m << (e - F64_FRAC_BITS);
    } else {
        if (m & ((1ull << (F64_FRAC_BITS - e)) - 1u)) { return false; }
        value = m >> (F64_FRAC_BITS - e);
    }
    *out = negative ? -(int64_t)value : (int64_t)value;
    return true;
}

/* Orders finite binary64 bit patterns as their values (sign-magnitude to two's-complement order). */
static int64_t f64_order_key(uint64_t bits) {
    if ((bits << 1) == 0u) { return 0; }  /* +0 and -0 */
    return (bits >> 63) ? -(int64_t)(bits & 0x7FFFFFFFFFFFFFFFull) : (int64_t)bits;
}

int f64_bits_compare_f32(uint64_t bits, float v) {
    int64_t a = f64_order_key(bits);
    int64_t b = f64_order_key(f64_bits_from_f32(v));
    return (a > b) - (a < b);
}
