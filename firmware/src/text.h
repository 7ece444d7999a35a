/* Bounded text building for ACK reasons and TEXT lines, without printf (small flash, no float printf). */
#ifndef TEXT_H
#define TEXT_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    char *buf;
    size_t cap;   /* bytes of buf, the terminating NUL included */
    size_t len;
} text_buffer_t;

void text_start(text_buffer_t *t, char *buf, size_t cap);
void text_add(text_buffer_t *t, const char *s);
/* At most n bytes of s, stopping at a NUL (for char[24] fields). */
void text_add_n(text_buffer_t *t, const char *s, size_t n);
void text_add_uint(text_buffer_t *t, uint32_t v);
void text_add_int(text_buffer_t *t, int32_t v);
/* Up to 3 decimals, trailing zeros dropped (enough for depths, volts and parameter bounds). */
void text_add_float(text_buffer_t *t, float v);
void text_copy(char *dst, size_t cap, const char *src);
const char *text_mode_name(uint8_t mode);

#endif
