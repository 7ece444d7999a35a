/* COBS encode / decode over caller buffers (no heap). */
#include "cobs.h"

size_t cobs_encode(const uint8_t *in, size_t n, uint8_t *out) {
    size_t code_at = 0;
    size_t o = 1;
    uint8_t code = 1;
    for (size_t i = 0; i < n; i++) {
        if (in[i] == 0u) {
            out[code_at] = code;
            code_at = o++;
            code = 1;
            continue;
        }
        out[o++] = in[i];
        code++;
        if (code == 0xFFu) {
            out[code_at] = code;
            if (i + 1u == n) { return o; }  /* canonical: no empty block after a full one at the end */
            code_at = o++;
            code = 1;
        }
    }
    out[code_at] = code;
    return o;
}

bool cobs_decode(const uint8_t *in, size_t n, uint8_t *out, size_t *out_n) {
    size_t i = 0;
    size_t o = 0;
    while (i < n) {
        uint8_t code = in[i++];
        if (code == 0u || i + (size_t)code - 1u > n) { return false; }
        for (uint8_t k = 1; k < code; k++) {
            uint8_t b = in[i++];
            if (b == 0u) { return false; }
            out[o++] = b;
        }
        if (code != 0xFFu && i < n) { out[o++] = 0u; }
    }
    *out_n = o;
    return true;
}
