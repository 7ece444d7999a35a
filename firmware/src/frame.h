/* Frames (SPEC.md s. 1): the streaming decoder with reject counters and sequence tracking, the encoder. */
#ifndef FRAME_H
#define FRAME_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "cobs.h"
#include "proto_messages.h"

#define FRAME_WIRE_MAX (COBS_MAX_ENCODED(PROTO_MAX_INNER) + 1u)  /* with the 0x00 delimiter */
#define FRAME_SEQ_HALF 0x8000u  /* a seq this far or more behind the expected one is late, not a gap */

/* Counters of one receiver (SPEC.md 1.1 / decisions: rx_frames, rx_rejects, rx_lost). */
typedef struct {
    uint32_t frames;        /* passed CRC and version checks and handed to the program */
    uint32_t oversize;
    uint32_t cobs_errors;
    uint32_t runts;
    uint32_t crc_errors;
    uint32_t incompatible;
    uint32_t unknown_id;    /* unknown ids outside the command range only */
    uint32_t malformed;     /* SIGNED set on a non-command frame too short for a trailer */
    uint32_t lost;          /* sequence gaps */
    uint32_t duplicates;
} frame_stats_t;

/* A received frame: the inner bytes (CRC included) and where its payload lies. */
typedef struct {
    uint8_t inner[PROTO_MAX_INNER];
    uint16_t inner_len;
    uint8_t flags;
    uint16_t seq;
    uint8_t msg_id;
    uint16_t payload_len;   /* without the signature trailer */
    bool truncated_signature;  /* a command with SIGNED set but no room for the trailer */
} frame_t;

typedef struct {
    uint8_t chunk[PROTO_MAX_CHUNK];
    uint16_t chunk_len;
    bool discarding;        /* inside an oversize chunk: drop bytes until the next 0x00 */
    bool synced;            /* sequence tracking has an expected seq */
    uint16_t expected_seq;
    frame_stats_t stats;
} frame_decoder_t;

void frame_decoder_init(frame_decoder_t *d);
/* Forget the expected seq (a new link, or a HELLO: the next frame synchronises). */
void frame_decoder_resync(frame_decoder_t *d);
/* Feeds one byte; true when it completed a frame the program must handle, written to *out. */
bool frame_decoder_push(frame_decoder_t *d, uint8_t byte, frame_t *out);
uint32_t frame_rejects(const frame_stats_t *s);

static inline const uint8_t *frame_payload(const frame_t *f) { return f->inner + PROTO_HEADER_BYTES; }

/* The sender's side: one seq counter for every frame sent. */
typedef struct {
    uint16_t next_seq;
} frame_encoder_t;

/* Builds the inner frame (header, payload, CRC) into inner; returns its length. */
size_t frame_build_inner(frame_encoder_t *e, uint8_t flags, uint8_t msg_id, const uint8_t *payload, size_t n,
                         uint8_t *inner);
/* COBS-encodes an inner frame and appends the 0x00 delimiter; returns the wire length. */
size_t frame_wire(const uint8_t *inner, size_t n, uint8_t *wire);

#endif
