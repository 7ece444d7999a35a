/* The streaming frame decoder and the encoder: bounded buffers, every reject counted by cause. */
#include "frame.h"

#include <string.h>

#include "crc.h"
#include "wire.h"

void frame_decoder_init(frame_decoder_t *d) { memset(d, 0, sizeof *d); }

void frame_decoder_resync(frame_decoder_t *d) { d->synced = false; }

uint32_t frame_rejects(const frame_stats_t *s) {
    return s->oversize + s->cobs_errors + s->runts + s->crc_errors + s->incompatible + s->unknown_id + s->malformed;
}

static void track_sequence(frame_decoder_t *d, uint16_t seq) {
    if (d->synced) {
        uint16_t gap = (uint16_t)(seq - d->expected_seq);
        if (gap >= FRAME_SEQ_HALF) {
            d->stats.duplicates++;
            return;
        }
        d->stats.lost += gap;
    }
    d->synced = true;
    d->expected_seq = (uint16_t)(seq + 1u);
}

static bool decode_chunk(frame_decoder_t *d, frame_t *f) {
    frame_stats_t *s = &d->stats;
    size_t n = 0;
    if (!cobs_decode(d->chunk, d->chunk_len, f->inner, &n)) {
        s->cobs_errors++;
        return false;
    }
    if (n < PROTO_MIN_INNER) {
        s->runts++;
        return false;
    }
    if (n > PROTO_MAX_INNER) {  /* 255 chunk bytes can decode to 254 at most; kept as a guard */
        s->oversize++;
        return false;
    }
    if (crc16(f->inner, n) != 0u) {  /* over the frame and its big-endian CRC, a good frame's CRC is 0 */
        s->crc_errors++;
        return false;
    }
    uint8_t version = f->inner[0];
    uint8_t flags = f->inner[1];
    if (version != PROTO_VERSION || (flags & PROTO_INCOMPATIBLE_FLAGS_MASK) != 0u) {
        s->incompatible++;
        return false;
    }
    f->inner_len = (uint16_t)n;
    f->flags = flags;
    f->seq = wire_get_u16(f->inner + 2);
    f->msg_id = f->inner[4];
    if (f->msg_id == MSG_HELLO_ID) { d->synced = false; }  /* a HELLO synchronises (decisions: O3) */
    track_sequence(d, f->seq);
    bool command = f->msg_id >= PROTO_COMMAND_IDS_FROM;
    if (!command && proto_message(f->msg_id) == NULL) {
        s->unknown_id++;
        return false;
    }
    size_t end = n - PROTO_CRC_BYTES;
    f->truncated_signature = false;
    if (flags & FRAME_FLAG_SIGNED) {
        if (n < PROTO_MIN_INNER + PROTO_TRAILER_BYTES) {
            if (!command) {
                s->malformed++;
                return false;
            }
            f->truncated_signature = true;  /* answered UNAUTHORIZED by the program */
            end = PROTO_HEADER_BYTES;
        } else {
            end -= PROTO_TRAILER_BYTES;
        }
    }
    f->payload_len = (uint16_t)(end - PROTO_HEADER_BYTES);
    s->frames++;
    return true;
}

bool frame_decoder_push(frame_decoder_t *d, uint8_t byte, frame_t *out) {
    if (byte != 0u) {
        if (d->discarding) { return false; }
        if (d->chunk_len >= PROTO_MAX_CHUNK) {  /* discard as it grows (decisions: C5) */
            d->stats.oversize++;
            d->discarding = true;
            d->chunk_len = 0;
            return false;
        }
        d->chunk[d->chunk_len++] = byte;
        return false;
    }
    bool was_discarding = d->discarding;
    size_t len = d->chunk_len;
    d->discarding = false;
    d->chunk_len = 0;
    if (was_discarding || len == 0u) { return false; }  /* empty chunk: line-noise flush, ignored */
    d->chunk_len = (uint16_t)len;
    bool ok = decode_chunk(d, out);
    d->chunk_len = 0;
    return ok;
}

size_t frame_build_inner(frame_encoder_t *e, uint8_t flags, uint8_t msg_id, const uint8_t *payload, size_t n,
                         uint8_t *inner) {
    if (n > PROTO_MAX_PAYLOAD) { n = PROTO_MAX_PAYLOAD; }
    inner[0] = PROTO_VERSION;
    inner[1] = flags;
    wire_put_u16(inner + 2, e->next_seq);
    e->next_seq = (uint16_t)(e->next_seq + 1u);
    inner[4] = msg_id;
    if (n > 0u && payload != inner + PROTO_HEADER_BYTES) { memmove(inner + PROTO_HEADER_BYTES, payload, n); }
    size_t len = PROTO_HEADER_BYTES + n;
    uint16_t crc = crc16(inner, len);
    inner[len] = (uint8_t)(crc >> 8);
    inner[len + 1u] = (uint8_t)crc;
    return len + PROTO_CRC_BYTES;
}

size_t frame_wire(const uint8_t *inner, size_t n, uint8_t *wire) {
    size_t len = cobs_encode(inner, n, wire);
    wire[len] = 0u;
    return len + 1u;
}
