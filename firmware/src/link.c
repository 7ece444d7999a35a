/* Link layer: one decoder for the ground, one encoder for everything the agent sends. */
#include "link.h"

#include <string.h>

#include "config.h"
#include "hal.h"
#include "logring.h"
#include "signing.h"
#include "text.h"
#include "wire.h"

#define READ_CHUNK_BYTES 64u

typedef struct {
    uint8_t msg_id;
    uint16_t seq;
    uint8_t result;
    bool used;
} answered_t;

static frame_decoder_t g_decoder;
static frame_encoder_t g_encoder;
static frame_t g_rx;                       /* the frame being handled */
static uint8_t g_inner[PROTO_MAX_INNER];   /* the frame being sent */
static uint8_t g_wire[FRAME_WIRE_MAX];
static answered_t g_answered[LINK_ACK_MEMORY];
static const link_upcalls_t *g_up;        /* the command handlers and the mode machine (agent.c) */
static uint8_t g_answered_next;
static uint32_t g_node_id;
static uint32_t g_boot_id;
static uint32_t g_signing_rejects;
static bool g_heard;                       /* a valid frame from the ground on this link */
static uint64_t g_next_hello_us;
static uint64_t g_next_heartbeat_us;
static uint64_t g_last_ground_rx_us;

static void write_inner(size_t len) {
    size_t n = frame_wire(g_inner, len, g_wire);
    hal_link_write(g_wire, n);
}

void link_send(uint8_t msg_id, const uint8_t *payload, size_t n, uint8_t flags) {
    write_inner(frame_build_inner(&g_encoder, flags, msg_id, payload, n, g_inner));
}

void link_send_logged(uint8_t msg_id, const uint8_t *payload, size_t n, uint32_t sample, bool is_sample) {
    size_t len = frame_build_inner(&g_encoder, 0, msg_id, payload, n, g_inner);
    logring_append(g_inner, (uint8_t)len, sample, is_sample);
    write_inner(len);
}

void link_send_replayed(const uint8_t *inner, size_t len) {
    if (len < PROTO_MIN_INNER) { return; }
    link_send(inner[4], inner + PROTO_HEADER_BYTES, len - PROTO_HEADER_BYTES - PROTO_CRC_BYTES,
              FRAME_FLAG_REPLAYED);
}

void link_text(uint8_t severity, const char *line) {
    uint8_t payload[PROTO_MAX_PAYLOAD];
    msg_text_t m;
    m.t_us = hal_time_us();
    m.severity = severity;
    m.text = (const uint8_t *)line;
    size_t n = strlen(line);
    m.text_len = (uint8_t)(n > MSG_TEXT_TAIL_MAX_BYTES ? MSG_TEXT_TAIL_MAX_BYTES : n);
    link_send(MSG_TEXT_ID, payload, msg_text_pack(&m, payload), 0);
}

static void send_hello(void) {
    uint8_t payload[PROTO_MAX_PAYLOAD];
    msg_hello_t m;
    memset(&m, 0, sizeof m);
    m.protocol_version = PROTO_VERSION;
    m.node_kind = NODE_KIND_AGENT;
    m.definitions_hash = PROTO_DEFINITIONS_HASH;
    m.firmware_major = CFG_FIRMWARE_MAJOR;
    m.firmware_minor = CFG_FIRMWARE_MINOR;
    m.firmware_patch = CFG_FIRMWARE_PATCH;
    m.node_id = g_node_id;
    m.boot_id = g_boot_id;
    m.generation = g_up->generation();
    text_add_n(&(text_buffer_t){m.name, sizeof m.name, 0}, CFG_AGENT_NAME, sizeof m.name - 1u);
    link_send(MSG_HELLO_ID, payload, msg_hello_pack(&m, payload), 0);
    g_next_hello_us = hal_link_time_us() + LINK_HELLO_REPEAT_US;
}

static void send_heartbeat(void) {
    uint8_t payload[PROTO_MAX_PAYLOAD];
    logring_info_t log;
    logring_info(&log);
    const frame_stats_t *s = &g_decoder.stats;
    msg_heartbeat_t m;
    m.uptime_ms = (uint32_t)(hal_time_us() / 1000u);
    m.mode = g_up->mode();
    float battery_v = hal_battery_v();
    m.battery_mv = (uint16_t)(battery_v > 0.0f ? battery_v * 1000.0f + 0.5f : 0.0f);
    m.rx_frames = s->frames;
    m.rx_rejects = frame_rejects(s);
    m.rx_lost = s->lost;
    m.log_first_sample = log.first_sample;
    m.log_next_sample = log.next_sample;
    m.episode = g_up->episode();
    m.signing_rejects = g_signing_rejects;
    m.generation = g_up->generation();
    link_send(MSG_HEARTBEAT_ID, payload, msg_heartbeat_pack(&m, payload), 0);
}

void link_init(uint32_t node_id, const uint8_t *key_or_null, const link_upcalls_t *up) {
    g_up = up;
    frame_decoder_init(&g_decoder);
    memset(&g_encoder, 0, sizeof g_encoder);
    memset(g_answered, 0, sizeof g_answered);
    g_answered_next = 0;
    g_node_id = node_id;
    g_boot_id = hal_entropy();
    if (g_boot_id == 0u) { g_boot_id = 1u; }
    g_signing_rejects = 0;
    g_last_ground_rx_us = 0;
    g_next_heartbeat_us = 0;
    signing_init(key_or_null);
    link_reset();
}

void link_reset(void) {
    frame_decoder_resync(&g_decoder);
    memset(g_answered, 0, sizeof g_answered);  /* 1.2 s. 5: a new link's seqs must not meet an old session's ACKs */
    g_heard = false;
    send_hello();
}

void link_tick(void) {
    if (hal_time_us() >= g_next_heartbeat_us) {
        g_next_heartbeat_us = hal_time_us() + LINK_HEARTBEAT_US;
        send_heartbeat();
    }
}

static void send_ack(const frame_t *f, uint8_t result, const char *reason) {
    uint8_t payload[PROTO_MAX_PAYLOAD];
    msg_ack_t m;
    m.cmd_msg_id = f->msg_id;
    m.cmd_seq = f->seq;
    m.result = result;
    m.reason = (const uint8_t *)reason;
    size_t n = strlen(reason);
    m.reason_len = (uint8_t)(n > MSG_ACK_TAIL_MAX_BYTES ? MSG_ACK_TAIL_MAX_BYTES : n);
    link_send(MSG_ACK_ID, payload, msg_ack_pack(&m, payload), 0);
}

static void alive(void) {
    g_heard = true;
    g_last_ground_rx_us = hal_link_time_us();
}

static const answered_t *answered(const frame_t *f) {
    for (unsigned i = 0; i < LINK_ACK_MEMORY; i++) {
        if (g_answered[i].used && g_answered[i].msg_id == f->msg_id && g_answered[i].seq == f->seq) {
            return &g_answered[i];
        }
    }
    return NULL;
}

#define RESYNC_NAME "resync"
#define RESYNC_NONCE_TEXT "; re-sync nonce "
#define RESYNCED "re-synced: the signing estimate, link ids and mark start again from this frame's timestamp"

/* `why`, then "; re-sync nonce " and the nonce in 8 lower-case hex digits (SPEC s. 12, "Re-sync"). */
static void refuse_naming_nonce(const frame_t *f, const char *why) {
    static const char hex[] = "0123456789abcdef";
    char reason[MSG_ACK_TAIL_MAX_BYTES + 1u];
    size_t n = strlen(why);
    size_t tail = sizeof RESYNC_NONCE_TEXT - 1u;
    if (n + tail + 8u > MSG_ACK_TAIL_MAX_BYTES) { n = MSG_ACK_TAIL_MAX_BYTES - tail - 8u; }
    memcpy(reason, why, n);
    memcpy(reason + n, RESYNC_NONCE_TEXT, tail);
    uint32_t nonce = signing_nonce();
    for (unsigned i = 0; i < 8u; i++) { reason[n + tail + i] = hex[(nonce >> (28u - 4u * i)) & 0xFu]; }
    reason[n + tail + 8u] = '\0';
    g_signing_rejects++;
    send_ack(f, ACK_RESULT_UNAUTHORIZED, reason);
}

static void refuse(const frame_t *f, sign_result_t r) {
    if (signing_refusal_names_nonce(r)) {
        refuse_naming_nonce(f, signing_reason(r));
        return;
    }
    g_signing_rejects++;
    send_ack(f, ACK_RESULT_UNAUTHORIZED, signing_reason(r));
}

static void remember(const frame_t *f, uint8_t result) {
    answered_t *slot = &g_answered[g_answered_next];
    g_answered_next = (uint8_t)((g_answered_next + 1u) % LINK_ACK_MEMORY);
    slot->msg_id = f->msg_id;
    slot->seq = f->seq;
    slot->result = result;
    slot->used = true;
}

/* PARAM_SET index -1 named `resync`: the signed re-sync, not a parameter; its value in *nonce. */
static bool is_resync(const frame_t *f, double *nonce) {
    if (f->msg_id != MSG_PARAM_SET_ID) { return false; }
    msg_param_set_t m;
    msg_param_set_unpack(&m, frame_payload(f), f->payload_len);
    if (m.index != -1 || strncmp(m.name, RESYNC_NAME, sizeof m.name) != 0) { return false; }
    memcpy(nonce, &m.value_bits, sizeof *nonce);
    return true;
}

/* Authenticated already; its timestamp is what it repairs, so steps 3-4 are not made. Each nonce re-syncs once. */
static void handle_resync(const frame_t *f, double nonce) {
    if (nonce != (double)signing_nonce()) {
        refuse_naming_nonce(f, "stale re-sync nonce");
        return;
    }
    signing_resync(f, hal_link_time_us());
    alive();
    remember(f, ACK_RESULT_ACCEPTED);
    send_ack(f, ACK_RESULT_ACCEPTED, RESYNCED);
}

/* ACK reason of a CMD_SURFACE run without a valid signature or timestamp (SPEC 1.2 s. 12): the fail-safe. */
#define UNVERIFIED_SURFACE "surfacing without a valid signature: the fail-safe"

static void handle_command(const frame_t *f) {
    /* 1.2 order: (1) SIGNED bit / truncated, (2) HMAC, (3) ACK memory, (4) replay / too old / too new.
       CMD_SURFACE is exempt from (2) and (4): anyone may make the agent surface, nobody may make it dive. */
    if (f->truncated_signature) {
        refuse(f, SIGN_TRUNCATED);
        return;
    }
    bool verified = true;
    if (signing_enabled()) {
        sign_result_t r = signing_check_hmac(f);
        if (r != SIGN_VALID) {
            if (f->msg_id != MSG_CMD_SURFACE_ID) {
                refuse(f, r);
                return;
            }
            verified = false;
        }
    }
    const answered_t *memory = answered(f);
    if (memory != NULL) {  /* a retry: the same result again, not executed again (reason may be empty) */
        if (!signing_enabled()) { alive(); }  /* with a key a replayed frame is no sign of life (1.2 s. 4) */
        send_ack(f, memory->result, "");
        return;
    }
    double nonce;
    if (signing_enabled() && verified && is_resync(f, &nonce)) {
        handle_resync(f, nonce);
        return;
    }
    if (signing_enabled() && verified) {
        sign_result_t r = signing_check_time(f, hal_link_time_us());
        if (r != SIGN_VALID && f->msg_id != MSG_CMD_SURFACE_ID) {
            refuse(f, r);
            return;
        }
        if (r == SIGN_VALID) { alive(); } else { verified = false; }
    } else if (!signing_enabled()) {
        alive();
    }
    verdict_t v;
    g_up->command(f, false, &v);
    remember(f, v.result);
    send_ack(f, v.result, verified || v.result != ACK_RESULT_ACCEPTED ? v.reason : UNVERIFIED_SURFACE);
    if (v.result == ACK_RESULT_ACCEPTED) { g_up->command(f, true, &v); }
}

static void handle_timesync(const frame_t *f) {
    msg_timesync_t m;
    msg_timesync_unpack(&m, frame_payload(f), f->payload_len);
    if (m.receive_us != 0u || m.transmit_us != 0u) { return; }  /* a reply to a request of ours: none sent */
    uint64_t t = hal_time_us();
    m.receive_us = t;
    m.transmit_us = t != 0u ? t : 1u;  /* a reply never carries transmit_us = 0 */
    uint8_t payload[MSG_TIMESYNC_FIXED_BYTES];
    link_send(MSG_TIMESYNC_ID, payload, msg_timesync_pack(&m, payload), 0);
}

static void handle_frame(const frame_t *f) {
    if (f->msg_id >= PROTO_COMMAND_IDS_FROM) {
        handle_command(f);
        return;
    }
    /* A non-command frame is a sign of life only when it would pass as a command (signed if we hold a key). */
    bool valid = !signing_enabled() ||
                 (signing_check_hmac(f) == SIGN_VALID && signing_check_time(f, hal_link_time_us()) == SIGN_VALID);
    if (valid) { alive(); }
    if (f->msg_id == MSG_HELLO_ID) {
        memset(g_answered, 0, sizeof g_answered);  /* a new session: the ACK memory starts empty (1.2 s. 5) */
        send_hello();  /* every ground HELLO is answered */
    } else if (f->msg_id == MSG_TIMESYNC_ID) {
        handle_timesync(f);
    }
}

void link_poll(void) {
    uint8_t buf[READ_CHUNK_BYTES];
    size_t n;
    while ((n = hal_link_read(buf, sizeof buf)) > 0u) {
        for (size_t i = 0; i < n; i++) {
            if (frame_decoder_push(&g_decoder, buf[i], &g_rx)) { handle_frame(&g_rx); }
        }
    }
    g_up->pump_replies();
    if (!g_heard && hal_link_time_us() >= g_next_hello_us) { send_hello(); }  /* until the ground is heard */
}

uint64_t link_last_ground_rx_us(void) { return g_last_ground_rx_us; }
const frame_stats_t *link_stats(void) { return &g_decoder.stats; }
uint32_t link_signing_rejects(void) { return g_signing_rejects; }
uint16_t link_next_seq(void) { return g_encoder.next_seq; }
