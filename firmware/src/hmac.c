/* HMAC-SHA256: key shorter than the block, so it is only padded (RFC 2104). */
#include "hmac.h"

#include <string.h>

void hmac_sha256(const uint8_t key[HMAC_KEY_BYTES], const uint8_t *msg, size_t n, uint8_t out[SHA256_DIGEST_BYTES]) {
    uint8_t pad[SHA256_BLOCK_BYTES];
    uint8_t inner[SHA256_DIGEST_BYTES];
    sha256_t s;
    memset(pad, 0x36, sizeof pad);
    for (unsigned i = 0; i < HMAC_KEY_BYTES; i++) { pad[i] ^= key[i]; }
    sha256_init(&s);
    sha256_update(&s, pad, sizeof pad);
    sha256_update(&s, msg, n);
    sha256_final(&s, inner);
    memset(pad, 0x5c, sizeof pad);
    for (unsigned i = 0; i < HMAC_KEY_BYTES; i++) { pad[i] ^= key[i]; }
    sha256_init(&s);
    sha256_update(&s, pad, sizeof pad);
    sha256_update(&s, inner, sizeof inner);
    sha256_final(&s, out);
}

bool hmac_equal(const uint8_t *a, const uint8_t *b, size_t n) {
    uint8_t diff = 0;
    for (size_t i = 0; i < n; i++) { diff |= (uint8_t)(a[i] ^ b[i]); }
    return diff == 0u;
}
