/* Log ring over hal_log_read/write: a circular byte space of whole records (u8 L, then L bytes).

   Records are never kept in part: before one is written, the oldest whole records are dropped until it
   fits. Its bytes may run past the end of the storage and continue at address 0 (reads and writes go
   through read_at / write_at, which wrap). Only head, tail and counters live in RAM. */
#include "logring.h"

#include <string.h>

#include "hal.h"
#include "wire.h"

static uint32_t g_capacity;
static uint32_t g_head;       /* address of the oldest record */
static uint32_t g_tail;       /* where the next record goes */
static uint32_t g_used;
static uint32_t g_records;
static uint32_t g_dropped;    /* records dropped since boot (cursors check it) */
static uint32_t g_first_sample;
static uint32_t g_next_sample;

static void read_at(uint32_t addr, uint8_t *buf, uint32_t n) {
    uint32_t first = g_capacity - addr;
    if (n <= first) {
        (void)hal_log_read(addr, buf, n);
    } else {
        (void)hal_log_read(addr, buf, first);
        (void)hal_log_read(0, buf + first, n - first);
    }
}

static void write_at(uint32_t addr, const uint8_t *buf, uint32_t n) {
    uint32_t first = g_capacity - addr;
    if (n <= first) {
        (void)hal_log_write(addr, buf, n);
    } else {
        (void)hal_log_write(addr, buf, first);
        (void)hal_log_write(0, buf + first, n - first);
    }
}

static uint32_t advance(uint32_t addr, uint32_t n) { return (uint32_t)(((uint64_t)addr + n) % g_capacity); }

/* The sample index a logged frame carries (SAMPLE.sample, EPISODE_*.sample). */
static uint32_t record_sample(const uint8_t *inner) {
    const uint8_t *payload = inner + PROTO_HEADER_BYTES;
    switch (inner[4]) {
    case MSG_SAMPLE_ID: return wire_get_u32(payload + MSG_SAMPLE_OFF_SAMPLE);
    case MSG_EPISODE_START_ID: return wire_get_u32(payload + MSG_EPISODE_START_OFF_SAMPLE);
    default: return wire_get_u32(payload + MSG_EPISODE_END_OFF_SAMPLE);
    }
}

/* Reads the header bytes of the record at addr: its length and its sample index. */
static uint8_t peek(uint32_t addr, uint32_t *sample, uint8_t *msg_id) {
    uint8_t head[1 + PROTO_HEADER_BYTES + 16u];
    read_at(addr, head, sizeof head <= g_capacity ? (uint32_t)sizeof head : g_capacity);
    *sample = record_sample(head + 1);
    *msg_id = head[1 + 4];
    return head[0];
}

static void drop_oldest(void) {
    uint32_t sample;
    uint8_t msg_id;
    uint8_t len = peek(g_head, &sample, &msg_id);
    g_head = advance(g_head, 1u + len);
    g_used -= 1u + len;
    g_records--;
    g_dropped++;
    if (g_records == 0u) {
        g_first_sample = g_next_sample;
    } else {
        (void)peek(g_head, &g_first_sample, &msg_id);
    }
}

void logring_init(void) {
    g_capacity = hal_log_capacity_bytes();
    g_head = g_tail = g_used = g_records = g_dropped = 0;
    g_first_sample = g_next_sample = 0;
}

void logring_append(const uint8_t *inner, uint8_t len, uint32_t sample, bool is_sample) {
    uint32_t size = 1u + len;
    if (g_capacity < size) { return; }
    while (g_capacity - g_used < size) { drop_oldest(); }
    write_at(g_tail, &len, 1);
    write_at(advance(g_tail, 1), inner, len);
    g_tail = advance(g_tail, size);
    if (g_records == 0u) { g_first_sample = sample; }
    g_used += size;
    g_records++;
    if (is_sample && sample >= g_next_sample) { g_next_sample = sample + 1u; }
}

void logring_info(logring_info_t *out) {
    out->first_sample = g_records ? g_first_sample : g_next_sample;
    out->next_sample = g_next_sample;
    out->bytes_used = g_used;
    out->capacity_bytes = g_capacity;
}

void logring_cursor_start(logring_cursor_t *c, uint32_t first_sample, uint32_t end_sample) {
    memset(c, 0, sizeof *c);
    c->end_sample = end_sample;
    c->active = end_sample > first_sample && g_records > 0u;
    c->addr = g_head;
    c->seq_at_start = g_dropped;
    /* Skip the records before first_sample (indices never decrease along the ring). */
    uint32_t left = g_records;
    while (c->active && left > 0u) {
        uint32_t sample;
        uint8_t msg_id;
        uint8_t len = peek(c->addr, &sample, &msg_id);
        if (sample >= first_sample) { return; }
        c->addr = advance(c->addr, 1u + len);
        left--;
    }
    c->active = false;
}

bool logring_cursor_next(logring_cursor_t *c, uint8_t *inner, uint8_t *len) {
    if (!c->active) { return false; }
    if (c->addr == g_tail || g_dropped != c->seq_at_start) {
        /* At the newest record, or the ring overwrote where the cursor stood: the replay ends here. */
        if (g_dropped != c->seq_at_start) {
            /* the records after the cursor are still in order; continue only if it was not overwritten */
            uint32_t from_head = (uint32_t)(((uint64_t)c->addr + g_capacity - g_head) % g_capacity);
            uint32_t tail_from_head = (uint32_t)(((uint64_t)g_tail + g_capacity - g_head) % g_capacity);
            if (g_records == 0u || from_head >= tail_from_head) { c->active = false; return false; }
            c->seq_at_start = g_dropped;
        } else {
            c->active = false;
            return false;
        }
    }
    uint32_t sample;
    uint8_t msg_id;
    uint8_t n = peek(c->addr, &sample, &msg_id);
    bool is_sample = msg_id == MSG_SAMPLE_ID;
    if (sample >= c->end_sample || (is_sample && c->samples >= LOGRING_REPLAY_MAX_SAMPLES)) {
        c->active = false;
        return false;
    }
    read_at(advance(c->addr, 1), inner, n);
    *len = n;
    c->addr = advance(c->addr, 1u + n);
    c->replayed++;
    if (is_sample) { c->samples++; }
    return true;
}
