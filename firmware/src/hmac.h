/* HMAC-SHA256 (RFC 2104) with a 32-byte key, and a constant-time compare. */
#ifndef HMAC_H
#define HMAC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "sha256.h"

#define HMAC_KEY_BYTES 32u

void hmac_sha256(const uint8_t key[HMAC_KEY_BYTES], const uint8_t *msg, size_t n, uint8_t out[SHA256_DIGEST_BYTES]);
/* Same bytes, in time independent of where they differ. */
bool hmac_equal(const uint8_t *a, const uint8_t *b, size_t n);

#endif
