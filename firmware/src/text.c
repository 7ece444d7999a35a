/* Bounded string building: never writes past cap, always NUL-terminated. */
#include "text.h"

#include "proto_messages.h"

void text_start(text_buffer_t *t, char *buf, size_t cap) {
    t->buf = buf;
    t->cap = cap;
    t->len = 0;
    if (cap > 0u) { buf[0] = '\0'; }
}

void text_add_n(text_buffer_t *t, const char *s, size_t n) {
    for (size_t i = 0; i < n && s[i] != '\0' && t->len + 1u < t->cap; i++) { t->buf[t->len++] = s[i]; }
    if (t->cap > 0u) { t->buf[t->len] = '\0'; }
}

void text_add(text_buffer_t *t, const char *s) { text_add_n(t, s, (size_t)-1); }

void text_add_uint(text_buffer_t *t, uint32_t v) {
    char digits[11];
    size_t n = 0;
    do {
        digits[n++] = (char)('0' + v % 10u);
        v /= 10u;
    } while (v != 0u);
    char out[11];
    for (size_t i = 0; i < n; i++) { out[i] = digits[n - 1u - i]; }
    text_add_n(t, out, n);
}

void text_add_int(text_buffer_t *t, int32_t v) {
    if (v < 0) {
        text_add(t, "-");
        text_add_uint(t, (uint32_t)(-(v + 1)) + 1u);
    } else {
        text_add_uint(t, (uint32_t)v);
    }
}

void text_add_float(text_buffer_t *t, float v) {
    if (v != v) { text_add(t, "nan"); return; }
    if (v < 0.0f) { text_add(t, "-"); v = -v; }
    if (v > 4.0e9f) { text_add(t, "inf"); return; }
    uint32_t milli = (uint32_t)(v * 1000.0f + 0.5f);
    text_add_uint(t, milli / 1000u);
    uint32_t frac = milli % 1000u;
    if (frac == 0u) { return; }
    char out[4] = {'.', (char)('0' + frac / 100u), (char)('0' + frac / 10u % 10u), (char)('0' + frac % 10u)};
    size_t n = 4;
    while (out[n - 1u] == '0') { n--; }
    text_add_n(t, out, n);
}

void text_copy(char *dst, size_t cap, const char *src) {
    text_buffer_t t;
    text_start(&t, dst, cap);
    text_add(&t, src);
}

const char *text_mode_name(uint8_t mode) { return proto_mode_name(mode); }
