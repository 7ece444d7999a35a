/* Command handlers and the reply streams (PARAM_LIST, CMD_DUMP, LOG_REQUEST) that follow their ACK. */
#include "commands.h"

#include <string.h>

#include "dumps.h"
#include "link.h"
#include "logring.h"
#include "modes.h"
#include "text.h"
#include "wire.h"

typedef enum { REPLY_NONE = 0, REPLY_PARAMS, REPLY_DUMP, REPLY_LOG } reply_kind_t;

/* The one reply stream in progress; a new one first finishes the old (replies stay in command order). */
typedef struct {
    reply_kind_t kind;
    uint16_t next_param;
    uint32_t dump_id;
    uint8_t dump_kind;
    uint32_t dump_episode;
    uint32_t dump_total;
    uint32_t dump_at;
    uint32_t dump_end;
    logring_cursor_t log;
} reply_t;

static reply_t g_reply;

void commands_init(void) { memset(&g_reply, 0, sizeof g_reply); }

static void send_param(uint16_t index) {
    uint8_t payload[PROTO_MAX_PAYLOAD];
    link_send(MSG_PARAM_VALUE_ID, payload, params_value_payload(index, payload), 0);
}

static bool pump_one(void) {
    switch (g_reply.kind) {
    case REPLY_PARAMS:
        if (g_reply.next_param >= PARAM_COUNT) { break; }
        send_param(g_reply.next_param++);
        return true;
    case REPLY_DUMP: {
        if (g_reply.dump_at >= g_reply.dump_end) { break; }
        uint32_t held_total = 0;
        uint32_t held_episode = 0;
        /* 1.2 s. 10: a live snapshot (COUNTS, shared Q_VALUES) that went STALE mid-sending is not sent on: its
           chunks would mix two models. The ground sees the missing range, asks again and gets STALE. */
        if (!dumps_find(g_reply.dump_id, g_reply.dump_kind, &held_total, &held_episode)) { break; }
        uint8_t payload[PROTO_MAX_PAYLOAD];
        uint8_t data[DUMPS_CHUNK_BYTES];
        uint32_t n = g_reply.dump_end - g_reply.dump_at;
        if (n > DUMPS_CHUNK_BYTES) { n = DUMPS_CHUNK_BYTES; }
        dumps_read(g_reply.dump_id, g_reply.dump_at, data, n);
        msg_dump_chunk_t m = {g_reply.dump_id, g_reply.dump_kind, g_reply.dump_episode, g_reply.dump_total,
                              g_reply.dump_at, data, (uint8_t)n};
        link_send(MSG_DUMP_CHUNK_ID, payload, msg_dump_chunk_pack(&m, payload), 0);
        g_reply.dump_at += n;
        return true;
    }
    case REPLY_LOG: {
        uint8_t inner[PROTO_MAX_INNER];
        uint8_t len = 0;
        if (logring_cursor_next(&g_reply.log, inner, &len)) {
            link_send_replayed(inner, len);
            return true;
        }
        logring_info_t info;
        logring_info(&info);
        uint8_t payload[MSG_LOG_RANGE_FIXED_BYTES];
        msg_log_range_t m = {info.first_sample, info.next_sample, g_reply.log.replayed, info.bytes_used,
                             info.capacity_bytes};
        link_send(MSG_LOG_RANGE_ID, payload, msg_log_range_pack(&m, payload), 0);
        break;
    }
    case REPLY_NONE:
        return false;
    }
    g_reply.kind = REPLY_NONE;
    return false;
}

static uint32_t reply_cost(void) {
    bool live_q = g_reply.kind == REPLY_DUMP && g_reply.dump_kind == DUMP_KIND_Q_VALUES && dumps_live(g_reply.dump_id);
    return live_q ? COMMANDS_LIVE_Q_CHUNK_COST : 1u;
}

bool commands_pump(uint32_t budget) {
    while (budget > 0u) {
        uint32_t cost = reply_cost();
        budget = budget > cost ? budget - cost : 0u;
        if (!pump_one()) { return false; }
    }
    return g_reply.kind != REPLY_NONE;
}

static void start_reply(reply_kind_t kind) {
    while (pump_one()) { }
    memset(&g_reply, 0, sizeof g_reply);
    g_reply.kind = kind;
}

static void cmd_dump(const msg_cmd_dump_t *m, bool apply, verdict_t *v) {
    text_buffer_t t;
    text_start(&t, v->reason, sizeof v->reason);
    if (m->kind < DUMP_KIND_VALUES || m->kind > DUMP_KIND_COUNTS) {
        text_add(&t, "no dump kind ");
        text_add_uint(&t, m->kind);
        v->result = ACK_RESULT_BAD_VALUE;
        return;
    }
    uint32_t total = 0;
    uint32_t episode = 0;
    uint32_t dump_id = m->dump_id;
    if (dump_id == 0u) {
        uint16_t states = learner_n_states();
        total = m->kind == DUMP_KIND_VALUES ? 4u * states : m->kind == DUMP_KIND_POLICY ? states
              : m->kind == DUMP_KIND_Q_VALUES ? 8u * states : 4u * (uint32_t)states * states;
    } else if (!dumps_find(dump_id, m->kind, &total, &episode)) {
        text_add(&t, "dump ");
        text_add_uint(&t, dump_id);
        text_add(&t, " no longer held");
        v->result = ACK_RESULT_STALE;
        return;
    }
    if (m->offset > total) {
        text_add(&t, "offset ");
        text_add_uint(&t, m->offset);
        text_add(&t, " past the ");
        text_add_uint(&t, total);
        text_add(&t, "-byte snapshot");
        v->result = ACK_RESULT_BAD_VALUE;
        return;
    }
    verdict_ok(v);
    if (!apply) { return; }
    start_reply(REPLY_DUMP);
    if (dump_id == 0u) {
        dump_id = dumps_take(m->kind);
        (void)dumps_find(dump_id, m->kind, &total, &episode);
    }
    uint32_t end = total;
    if (m->length != 0u && m->length < total - m->offset) { end = m->offset + m->length; }
    g_reply.dump_id = dump_id;
    g_reply.dump_kind = m->kind;
    g_reply.dump_episode = episode;
    g_reply.dump_total = total;
    g_reply.dump_at = m->offset;
    g_reply.dump_end = end;
}

void commands_episode_dumps(void) {
    static const uint8_t kinds[2] = {DUMP_KIND_VALUES, DUMP_KIND_POLICY};
    for (unsigned i = 0; i < 2u; i++) {
        msg_cmd_dump_t m = {kinds[i], 0u, 0u, 0u};
        verdict_t v;
        cmd_dump(&m, true, &v);
    }
}

void commands_handle(const frame_t *f, bool apply, verdict_t *v) {
    const uint8_t *p = frame_payload(f);
    size_t n = f->payload_len;
    verdict_ok(v);
    switch (f->msg_id) {
    case MSG_CMD_START_ID: {
        msg_cmd_start_t m;
        msg_cmd_start_unpack(&m, p, n);
        modes_cmd_start(m.max_episodes, apply, v);
        return;
    }
    case MSG_CMD_STOP_ID: modes_cmd_stop(apply, v); return;
    case MSG_CMD_PAUSE_ID: modes_cmd_pause(apply, v); return;
    case MSG_CMD_SURFACE_ID: modes_cmd_surface(apply, v); return;
    case MSG_CMD_RESET_MODEL_ID: modes_cmd_reset_model(apply, v); return;
    case MSG_CMD_SET_TARGET_ID: {
        msg_cmd_set_target_t m;
        msg_cmd_set_target_unpack(&m, p, n);
        modes_param_set(PARAM_TARGET_DEPTH_M, f64_bits_from_f32(m.target_depth_m), apply, v);
        return;
    }
    case MSG_CMD_HOVER_ID: {
        msg_cmd_hover_t m;
        msg_cmd_hover_unpack(&m, p, n);
        modes_cmd_hover(m.depth_m, apply, v);
        return;
    }
    case MSG_CMD_DUMP_ID: {
        msg_cmd_dump_t m;
        msg_cmd_dump_unpack(&m, p, n);
        cmd_dump(&m, apply, v);
        return;
    }
    case MSG_PARAM_LIST_ID:
        if (apply) { start_reply(REPLY_PARAMS); }
        return;
    case MSG_PARAM_GET_ID: {
        msg_param_get_t m;
        uint16_t index = 0;
        msg_param_get_unpack(&m, p, n);
        if (params_lookup(m.index, m.name, &index, v) && apply) {
            start_reply(REPLY_NONE);
            send_param(index);
        }
        return;
    }
    case MSG_PARAM_SET_ID: {
        msg_param_set_t m;
        uint16_t index = 0;
        msg_param_set_unpack(&m, p, n);
        if (!params_lookup(m.index, m.name, &index, v)) { return; }
        modes_param_set(index, m.value_bits, apply, v);
        if (apply && v->result == ACK_RESULT_ACCEPTED) {
            start_reply(REPLY_NONE);
            send_param(index);  /* one PARAM_VALUE with the value as stored; none after a NACK */
        }
        return;
    }
    case MSG_LOG_REQUEST_ID: {
        msg_log_request_t m;
        msg_log_request_unpack(&m, p, n);
        if (apply) {
            start_reply(REPLY_LOG);
            logring_cursor_start(&g_reply.log, m.first_sample, m.end_sample);
        }
        return;
    }
    default:
        verdict_set(v, ACK_RESULT_UNSUPPORTED, "command not implemented");
        return;
    }
}
