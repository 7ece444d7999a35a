/* Little-endian field access and the f32 <-> f64 bit conversions the core needs without double. */
#ifndef WIRE_H
#define WIRE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

void     wire_put_u16(uint8_t *p, uint16_t v);
void     wire_put_u32(uint8_t *p, uint32_t v);
void     wire_put_u64(uint8_t *p, uint64_t v);
void     wire_put_f32(uint8_t *p, float v);
uint16_t wire_get_u16(const uint8_t *p);
uint32_t wire_get_u32(const uint8_t *p);
uint64_t wire_get_u64(const uint8_t *p);
float    wire_get_f32(const uint8_t *p);

/* payload itself when it holds `size` bytes, else buf holding it zero-extended (append-only rule). */
const uint8_t *wire_zero_extend(uint8_t *buf, size_t size, const uint8_t *payload, size_t n);

uint32_t f32_bits(float v);
float    f32_from_bits(uint32_t bits);
/* The f32 widened exactly to binary64 bits (PARAM_VALUE carries stored f32 values as f64). */
uint64_t f64_bits_from_f32(float v);
bool     f64_bits_finite(uint64_t bits);
/* Round-to-nearest-even of a finite binary64 to f32 (inf when it overflows). */
float    f64_bits_to_f32(uint64_t bits);
/* A finite binary64 that is an integer in [-2^62, 2^62]: its value in *out. */
bool     f64_bits_to_integer(uint64_t bits, int64_t *out);
/* Exact comparison of a finite binary64 with a float: -1, 0, 1. */
int      f64_bits_compare_f32(uint64_t bits, float v);

#endif
