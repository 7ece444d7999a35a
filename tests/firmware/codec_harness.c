/* Test driver of the firmware codec (frame, COBS, CRC, generated messages, HMAC), one command per stdin line:
     D <wire hex>            decode: per frame "F flags seq msg_id payload_hex", its fields "  name=value",
                             "  repack=ok|differs"; then "R oversize cobs runts crc incompatible unknown malformed
                             lost duplicates frames"
     E <flags> <seq> <msg_id> <payload hex>   encode: "W <wire hex>"
     H <key hex> <inner hex> HMAC check of a signed inner frame: "H valid|bad"
   Values: integers in decimal, f32/f64 as their bit patterns in decimal, char[24] / tails as hex. */
#include <inttypes.h>
#include <stdio.h>
#include <string.h>

#include "frame.h"
#include "hmac.h"
#include "wire.h"

typedef struct { uint8_t msg_id; uint8_t offset; uint8_t type; const char *name; } proto_field_t;
extern const proto_field_t proto_fields[];
extern const size_t proto_field_count;
size_t proto_repack(uint8_t msg_id, const uint8_t *payload, size_t n, uint8_t *out);

#define LINE_BYTES 4096

static size_t from_hex(const char *s, uint8_t *out, size_t cap) {
    size_t n = 0;
    while (s[0] && s[1] && s[0] != ' ' && s[0] != '\n' && n < cap) {
        unsigned v;
        if (sscanf(s, "%2x", &v) != 1) { break; }
        out[n++] = (uint8_t)v;
        s += 2;
    }
    return n;
}

static void print_hex(const uint8_t *p, size_t n) {
    for (size_t i = 0; i < n; i++) { printf("%02x", p[i]); }
}

static void print_fields(const frame_t *f) {
    uint8_t full[PROTO_MAX_PAYLOAD] = {0};
    const uint8_t *payload = frame_payload(f);
    size_t n = f->payload_len;
    memcpy(full, payload, n);
    for (size_t i = 0; i < proto_field_count; i++) {
        const proto_field_t *d = &proto_fields[i];
        if (d->msg_id != f->msg_id) { continue; }
        const uint8_t *p = full + d->offset;
        printf("  %s=", d->name);
        switch (d->type) {
        case 1: printf("%u", p[0]); break;
        case 2: printf("%u", wire_get_u16(p)); break;
        case 3: case 9: printf("%" PRIu32, wire_get_u32(p)); break;
        case 4: case 10: printf("%" PRIu64, wire_get_u64(p)); break;
        case 5: printf("%d", (int8_t)p[0]); break;
        case 6: printf("%d", (int16_t)wire_get_u16(p)); break;
        case 7: printf("%" PRId32, (int32_t)wire_get_u32(p)); break;
        case 8: printf("%" PRId64, (int64_t)wire_get_u64(p)); break;
        case 11: print_hex(p, 24); break;
        default: if (n > d->offset) { print_hex(payload + d->offset, n - d->offset); } break;
        }
        printf("\n");
    }
    uint8_t out[PROTO_MAX_PAYLOAD];
    size_t m = proto_repack(f->msg_id, payload, n, out);
    const proto_msg_info_t *info = proto_message(f->msg_id);
    bool full_length = info != NULL && n >= info->fixed_bytes;
    if (full_length) { printf("  repack=%s\n", m == n && memcmp(out, payload, n) == 0 ? "ok" : "differs"); }
}

int main(void) {
    static char line[LINE_BYTES];
    static uint8_t bytes[LINE_BYTES / 2];
    static frame_decoder_t dec;
    static frame_t frame;
    frame_decoder_init(&dec);
    while (fgets(line, sizeof line, stdin) != NULL) {
        if (line[0] == 'D') {
            size_t n = from_hex(line + 2, bytes, sizeof bytes);
            for (size_t i = 0; i < n; i++) {
                if (frame_decoder_push(&dec, bytes[i], &frame)) {
                    printf("F %u %u %u ", frame.flags, frame.seq, frame.msg_id);
                    print_hex(frame_payload(&frame), frame.payload_len);
                    printf("\n");
                    print_fields(&frame);
                }
            }
            const frame_stats_t *s = &dec.stats;
            printf("R %u %u %u %u %u %u %u %u %u %u\n", s->oversize, s->cobs_errors, s->runts, s->crc_errors,
                   s->incompatible, s->unknown_id, s->malformed, s->lost, s->duplicates, s->frames);
        } else if (line[0] == 'E') {
            unsigned flags, seq, msg_id;
            char hex[LINE_BYTES];
            hex[0] = '\0';
            if (sscanf(line + 2, "%u %u %u %s", &flags, &seq, &msg_id, hex) < 3) { continue; }
            size_t n = from_hex(hex, bytes, sizeof bytes);
            frame_encoder_t enc = {(uint16_t)seq};
            uint8_t inner[PROTO_MAX_INNER];
            uint8_t wire[FRAME_WIRE_MAX];
            size_t len = frame_build_inner(&enc, (uint8_t)flags, (uint8_t)msg_id, bytes, n, inner);
            printf("W ");
            print_hex(wire, frame_wire(inner, len, wire));
            printf("\n");
        } else if (line[0] == 'H') {
            uint8_t key[HMAC_KEY_BYTES];
            char key_hex[80], inner_hex[LINE_BYTES];
            if (sscanf(line + 2, "%79s %4000s", key_hex, inner_hex) != 2) { continue; }
            from_hex(key_hex, key, sizeof key);
            size_t n = from_hex(inner_hex, bytes, sizeof bytes);
            uint8_t digest[SHA256_DIGEST_BYTES];
            size_t sig_at = n - PROTO_CRC_BYTES - 6u;
            hmac_sha256(key, bytes, sig_at, digest);
            printf("H %s\n", hmac_equal(digest, bytes + sig_at, 6) ? "valid" : "bad");
        }
        fflush(stdout);
    }
    return 0;
}
