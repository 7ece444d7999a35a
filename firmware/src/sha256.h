/* SHA-256 (FIPS 180-4), incremental, for HMAC-SHA256 command signing. */
#ifndef SHA256_H
#define SHA256_H

#include <stddef.h>
#include <stdint.h>

#define SHA256_BLOCK_BYTES 64u
#define SHA256_DIGEST_BYTES 32u

typedef struct {
    uint32_t h[8];
    uint64_t total_bytes;
    uint8_t block[SHA256_BLOCK_BYTES];
    uint8_t block_len;
} sha256_t;

void sha256_init(sha256_t *s);
void sha256_update(sha256_t *s, const uint8_t *p, size_t n);
void sha256_final(sha256_t *s, uint8_t digest[SHA256_DIGEST_BYTES]);

#endif
