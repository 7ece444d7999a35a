/* Snapshot store: 4 slots; VALUES / POLICY / Q_VALUES are copies in one arena, COUNTS is read live, and so is
   Q_VALUES of a shared-model learner (computed from its values and histograms: SPEC.md s. 10 and 13). */
#include "dumps.h"

#include <string.h>

#include "learner.h"
#include "proto_messages.h"
#include "wire.h"

typedef struct {
    uint32_t dump_id;   /* 0: free */
    uint32_t episode;
    uint32_t total_bytes;
    uint32_t age;       /* higher = newer */
    uint8_t kind;
    bool live;          /* rendered from the learner when read: COUNTS, a shared model's Q_VALUES */
    bool stale;         /* a live one after the model (or a shared model's values) changed */
} slot_t;

static uint8_t g_arena[DUMPS_ARENA_BYTES];
static slot_t g_slots[PARAM_SNAPSHOTS_HELD];
static uint32_t g_next_id;
static uint32_t g_age;

#define SLOT_BYTES (DUMPS_ARENA_BYTES / PARAM_SNAPSHOTS_HELD)

uint32_t dumps_max_states(bool shared_model) {
    return SLOT_BYTES / (shared_model ? PARAM_SHARED_SNAPSHOT_BYTES_PER_STATE : PARAM_SNAPSHOT_BYTES_PER_STATE);
}

void dumps_init(void) {
    memset(g_slots, 0, sizeof g_slots);
    g_next_id = 1;
    g_age = 0;
}

void dumps_model_changed(void) {
    for (unsigned i = 0; i < PARAM_SNAPSHOTS_HELD; i++) {
        if (g_slots[i].live) { g_slots[i].stale = true; }
    }
}

static uint32_t snapshot_bytes(uint8_t kind, uint32_t states) {
    switch (kind) {
    case DUMP_KIND_VALUES: return 4u * states;
    case DUMP_KIND_POLICY: return states;
    case DUMP_KIND_Q_VALUES: return 8u * states;
    default: return LEARNER_ACTIONS * 2u * states * states;
    }
}

/* Policy byte of state s: 255 where the state was never left (untried), as simulator/agent_dumps.py. */
static uint8_t policy_byte(uint16_t s) {
    return learner_tried(s) ? learner_policy(s) : ACTION_NONE;
}

static void render(uint8_t kind, uint8_t *out, uint16_t states) {
    for (uint16_t s = 0; s < states; s++) {
        if (kind == DUMP_KIND_VALUES) {
            wire_put_f32(out + 4u * s, learner_value(s));
        } else if (kind == DUMP_KIND_POLICY) {
            out[s] = policy_byte(s);
        } else {
            wire_put_f32(out + 8u * s, learner_q(s, 0));
            wire_put_f32(out + 8u * s + 4u, learner_q(s, 1));
        }
    }
}

uint32_t dumps_take(uint8_t kind) {
    slot_t *slot = &g_slots[0];
    for (unsigned i = 0; i < PARAM_SNAPSHOTS_HELD; i++) {
        if (g_slots[i].dump_id == 0u) { slot = &g_slots[i]; break; }
        if (g_slots[i].age < slot->age) { slot = &g_slots[i]; }
    }
    uint16_t states = learner_n_states();
    slot->dump_id = g_next_id;
    g_next_id = g_next_id == 0xFFFFFFFFu ? 1u : g_next_id + 1u;
    slot->kind = kind;
    slot->episode = learner_episode();
    slot->total_bytes = snapshot_bytes(kind, states);
    slot->age = ++g_age;
    slot->stale = false;
    slot->live = kind == DUMP_KIND_COUNTS || (kind == DUMP_KIND_Q_VALUES && learner_config()->shared_model);
    if (!slot->live && slot->total_bytes <= SLOT_BYTES) {
        render(kind, g_arena + (uint32_t)(slot - g_slots) * SLOT_BYTES, states);
    }
    return slot->dump_id;
}

static const slot_t *find(uint32_t dump_id, uint8_t kind) {
    for (unsigned i = 0; i < PARAM_SNAPSHOTS_HELD; i++) {
        const slot_t *slot = &g_slots[i];
        if (dump_id != 0u && slot->dump_id == dump_id && slot->kind == kind && !slot->stale) { return slot; }
    }
    return NULL;
}

bool dumps_live(uint32_t dump_id) {
    for (unsigned i = 0; i < PARAM_SNAPSHOTS_HELD; i++) {
        if (g_slots[i].dump_id == dump_id) { return g_slots[i].live; }
    }
    return false;
}

bool dumps_find(uint32_t dump_id, uint8_t kind, uint32_t *total_bytes, uint32_t *episode) {
    const slot_t *slot = find(dump_id, kind);
    if (slot == NULL) { return false; }
    *total_bytes = slot->total_bytes;
    *episode = slot->episode;
    return true;
}

void dumps_read(uint32_t dump_id, uint32_t offset, uint8_t *out, uint32_t n) {
    const slot_t *slot = NULL;
    for (unsigned i = 0; i < PARAM_SNAPSHOTS_HELD; i++) {
        if (g_slots[i].dump_id == dump_id) { slot = &g_slots[i]; }
    }
    if (slot == NULL) { return; }
    if (!slot->live) {
        memcpy(out, g_arena + (uint32_t)(slot - g_slots) * SLOT_BYTES + offset, n);
        return;
    }
    if (slot->kind == DUMP_KIND_Q_VALUES) {
        /* f32 q[S][2], little-endian, from the live values and histograms: each Q computed once. */
        uint8_t word[4];
        uint32_t word_at = 0xFFFFFFFFu;
        for (uint32_t i = 0; i < n; i++) {
            uint32_t pos = offset + i;
            if (pos / 4u != word_at) {
                word_at = pos / 4u;
                wire_put_f32(word, learner_q((uint16_t)(word_at / 2u), (uint8_t)(word_at % 2u)));
            }
            out[i] = word[pos % 4u];
        }
        return;
    }
    /* u16 count[2][S][S] little-endian, rendered from the live model byte by byte. */
    uint32_t states = learner_n_states();
    for (uint32_t i = 0; i < n; i++) {
        uint32_t pos = offset + i;
        uint32_t cell = pos / 2u;
        uint8_t a = (uint8_t)(cell / (states * states));
        uint16_t s = (uint16_t)((cell / states) % states);
        uint16_t t = (uint16_t)(cell % states);
        uint16_t count = learner_count(a, s, t);
        out[i] = (pos & 1u) ? (uint8_t)(count >> 8) : (uint8_t)count;
    }
}
