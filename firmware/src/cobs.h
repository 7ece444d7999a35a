/* Consistent Overhead Byte Stuffing (canonical, as the Python `cobs` package encodes). */
#ifndef COBS_H
#define COBS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

/* Bytes COBS(n bytes) takes at most, delimiter excluded. */
#define COBS_MAX_ENCODED(n) ((n) + (n) / 254u + 1u)

/* Encodes n bytes into out (room for COBS_MAX_ENCODED(n)); returns the encoded length, no delimiter. */
size_t cobs_encode(const uint8_t *in, size_t n, uint8_t *out);
/* Decodes a chunk (no 0x00 in it) into out (room for n bytes); false on a COBS error
   (a zero byte, or a code pointing past the end). Non-canonical input is accepted if it decodes. */
bool cobs_decode(const uint8_t *in, size_t n, uint8_t *out, size_t *out_n);

#endif
