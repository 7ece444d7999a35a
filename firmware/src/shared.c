/* The shared-model learner's model (learning/shared.py): layout in learner.c's arena, recording, inspection.

   Arena order: shared_type_t types[T], float values[S], float new_values[S] (Jacobi only),
   local counts[2 S] (Dirichlet only), uint8_t policy[ceil(S / 4)] (2 bits per state), uint8_t
   greedy[ceil(S / 8)] (1 bit per state, only with plan_stable_sweeps), uint16_t since_plan[T] (only with
   plan_growth), each of the last three in whole words. Planning is in shared_plan.c. */
#include "shared_internal.h"

#include <math.h>
#include <string.h>

_Static_assert(sizeof(shared_type_t) == 3u * SHARED_SLOTS + 4u, "the Teensy layout: 40 B per type");
_Static_assert(sizeof(shared_local8_t) == 3u * SHARED_SLOTS, "uint8 successor + uint16 count per slot");
_Static_assert(sizeof(shared_local16_t) == 4u * SHARED_SLOTS, "uint16 successor + uint16 count per slot");

shared_learner_t g_shared;

static uint32_t states_of(const learner_config_t *c)
{
    return (uint32_t)c->z_cells * c->zdot_cells * c->act_bins + 1u;
}

static uint32_t local_bytes(const learner_config_t *c)
{
    if (!(c->dirichlet_w > 0.0f)) {
        return 0u;
    }
    uint32_t per_pair = states_of(c) <= STATE_INDEX_U8_LIMIT ? (uint32_t)sizeof(shared_local8_t)
                                                             : (uint32_t)sizeof(shared_local16_t);
    return states_of(c) * LEARNER_ACTIONS * per_pair;
}

uint32_t shared_memory_bytes(const learner_config_t *c)
{
    return types_of(c) * (uint32_t)sizeof(shared_type_t) + states_of(c) * (uint32_t)sizeof(float) + local_bytes(c);
}

static uint32_t policy_bytes(uint32_t states)
{
    uint32_t bytes = (states + POLICY_STATES_PER_BYTE - 1u) / POLICY_STATES_PER_BYTE;
    return (bytes + 3u) & ~3u;
}

/* The early planning stop's last greedy action per state, 1 bit each in whole words (none when it is off). */
static uint32_t greedy_bytes(const learner_config_t *c)
{
    return c->plan_stable_sweeps > 0u ? ((states_of(c) + 7u) / 8u + 3u) & ~3u : 0u;
}

/* Planning on growth's count per type since the last plan, a uint16 each in whole words (none when it is off). */
static uint32_t since_plan_bytes(const learner_config_t *c)
{
    return c->plan_growth > 0.0f ? (types_of(c) * (uint32_t)sizeof(uint16_t) + 3u) & ~3u : 0u;
}

uint32_t shared_total_bytes(const learner_config_t *c)
{
    uint32_t sweep_buffer = c->in_place_sweeps ? 0u : states_of(c) * (uint32_t)sizeof(float);
    return shared_memory_bytes(c) + sweep_buffer + policy_bytes(states_of(c)) + greedy_bytes(c)
           + since_plan_bytes(c);
}

void shared_carve(uint8_t *base, const learner_config_t *c)
{
    g_shared.cfg = *c;
    g_shared.n_states = states_of(c);
    g_shared.terminal = g_shared.n_states - 1u;
    g_shared.dirichlet = c->dirichlet_w > 0.0f;
    g_shared.wide = g_shared.n_states > STATE_INDEX_U8_LIMIT;
    uint32_t off = 0u;
    g_shared.types = (shared_type_t *)(void *)(base + off);
    off += types_of(c) * (uint32_t)sizeof(shared_type_t);
    g_shared.values = (float *)(void *)(base + off);
    off += g_shared.n_states * (uint32_t)sizeof(float);
    g_shared.new_values = g_shared.values;
    if (!c->in_place_sweeps) {
        g_shared.new_values = (float *)(void *)(base + off);
        off += g_shared.n_states * (uint32_t)sizeof(float);
    }
    g_shared.local8 = NULL;
    g_shared.local16 = NULL;
    if (g_shared.dirichlet && g_shared.wide) {
        g_shared.local16 = (shared_local16_t *)(void *)(base + off);
    } else if (g_shared.dirichlet) {
        g_shared.local8 = (shared_local8_t *)(void *)(base + off);
    }
    off += local_bytes(c);
    g_shared.policy = base + off;
    off += policy_bytes(g_shared.n_states);
    g_shared.greedy = c->plan_stable_sweeps > 0u ? base + off : NULL;
    off += greedy_bytes(c);
    g_shared.since_plan = c->plan_growth > 0.0f ? (uint16_t *)(void *)(base + off) : NULL;
    /* learning.shared.cell_reward: minus the distance of the depth cell's centre from the target. */
    for (uint32_t iz = 0u; iz < c->z_cells && iz < SHARED_MAX_Z_CELLS; iz++) {
        g_shared.z_reward[iz] = -fabsf(-c->z_tol_m + ((float)iz + 0.5f) * 2.0f * c->z_tol_m / (float)c->z_cells);
    }
    /* ... minus vel_penalty times the velocity cell's centre speed (0 when off: the reward unchanged, x - 0 = x). */
    for (uint32_t iv = 0u; iv < c->zdot_cells && iv < SHARED_MAX_ZDOT_CELLS; iv++) {
        float centre = -c->zdot_tol_mps + ((float)iv + 0.5f) * 2.0f * c->zdot_tol_mps / (float)c->zdot_cells;
        g_shared.v_penalty[iv] = c->vel_penalty > 0.0f ? c->vel_penalty * fabsf(centre) : 0.0f;
    }
    g_shared.planning = false;
    g_shared.sweeps = 0u;
}

void shared_reset(void)
{
    g_shared.planning = false;
    g_shared.sweeps = 0u;
}

/* ------------------------------------------------------------------ grid codes */

/* learning.shared._raw: the cell on the grid extended by one region width each side. */
static int32_t raw_index(float x, float half_width, uint8_t cells)
{
    float i = floorf((x + half_width) / (2.0f * half_width) * (float)cells);
    int32_t n = (int32_t)cells;
    if (!(i > (float)-n)) {
        return -n;
    }
    return i >= (float)(2 * n - 1) ? 2 * n - 1 : (int32_t)i;
}

uint32_t shared_raw_cell(float depth_m, float velocity_mps, float target_m, float actuator_fraction)
{
    const learner_config_t *c = &g_shared.cfg;
    uint32_t rz = (uint32_t)(raw_index(depth_m - target_m, c->z_tol_m, c->z_cells) + c->z_cells);
    uint32_t rv = (uint32_t)(raw_index(velocity_mps, c->zdot_tol_mps, c->zdot_cells) + c->zdot_cells);
    uint32_t ib = 0u;
    if (c->act_bins > 1u) {
        float b = floorf((actuator_fraction + 1.0f) / 2.0f * (float)c->act_bins);
        ib = !(b > 0.0f) ? 0u : b >= (float)(c->act_bins - 1u) ? c->act_bins - 1u : (uint32_t)b;
    }
    return (ib * 3u * c->z_cells + rz) * 3u * c->zdot_cells + rv;
}

uint32_t shared_state_cell(uint32_t s)
{
    const learner_config_t *c = &g_shared.cfg;
    uint32_t iv = s % c->zdot_cells;
    uint32_t iz = (s / c->zdot_cells) % c->z_cells;
    uint32_t ib = s / ((uint32_t)c->zdot_cells * c->z_cells);
    return (ib * 3u * c->z_cells + iz + c->z_cells) * 3u * c->zdot_cells + iv + c->zdot_cells;
}

static uint8_t offset_code(int32_t dz, int32_t dv, int32_t db)
{
    if (dz < -DZ_MAX || dz > DZ_MAX || dv < -DV_MAX || dv > DV_MAX || db < -DB_MAX || db > DB_MAX) {
        return (uint8_t)SHARED_FAR;
    }
    return (uint8_t)(((dz + DZ_MAX) * DV_SPAN + (dv + DV_MAX)) * DB_SPAN + (db + DB_MAX));
}

/* ------------------------------------------------------------------ recording */

/* The slot of key among n slots (count > 0 and matching), or a free one, or the rarest (evicted). */
static uint32_t find_slot(const uint16_t *count, uint32_t key, bool wide, const void *keys, bool *evict)
{
    int32_t free_slot = -1;
    for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
        if (count[k] > 0u) {
            uint32_t have = wide ? ((const uint16_t *)keys)[k] : ((const uint8_t *)keys)[k];
            if (have == key) {
                *evict = false;
                return k;
            }
        } else if (free_slot < 0) {
            free_slot = (int32_t)k;
        }
    }
    *evict = free_slot < 0;
    if (free_slot < 0) {
        free_slot = 0;
        for (uint32_t k = 1u; k < SHARED_SLOTS; k++) {
            if (count[k] < count[free_slot]) {
                free_slot = (int32_t)k;
            }
        }
    }
    return (uint32_t)free_slot;
}

static void record_type(uint32_t t, uint8_t code)
{
    shared_type_t *ty = &g_shared.types[t];
    bool evict = false;
    uint32_t slot = find_slot(ty->count, code, false, ty->code, &evict);
    if (evict) {
        ty->total = (uint16_t)(ty->total - ty->count[slot]);
        ty->count[slot] = 0u;
        if (ty->evictions < LEARNER_COUNT_MAX) {
            ty->evictions++;
        }
    }
    if (ty->count[slot] == 0u) {
        ty->code[slot] = code;
    }
    if (ty->total == LEARNER_COUNT_MAX) {
        /* Saturation: halve every count (rounding up), the total recomputed. */
        uint32_t total = 0u;
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            ty->count[k] = (uint16_t)((ty->count[k] + 1u) / 2u);
            total += ty->count[k];
        }
        ty->total = (uint16_t)total;
    }
    ty->count[slot]++;
    ty->total++;
}

/* learning.model.record_transition on the local slots (the reward sums are not kept: unused). */
static void record_local(uint32_t pair, uint32_t s_next)
{
    uint16_t *count = local_counts(pair);
    const void *keys = g_shared.wide ? (const void *)g_shared.local16[pair].succ : (const void *)g_shared.local8[pair].succ;
    bool evict = false;
    uint32_t slot = find_slot(count, s_next, g_shared.wide, keys, &evict);
    if (evict || count[slot] == 0u) {
        count[slot] = 0u;
        if (g_shared.wide) {
            g_shared.local16[pair].succ[slot] = (uint16_t)s_next;
        } else {
            g_shared.local8[pair].succ[slot] = (uint8_t)s_next;
        }
    }
    if (count[slot] == LEARNER_COUNT_MAX) {
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            count[k] = (uint16_t)((count[k] + 1u) / 2u);
        }
    }
    count[slot]++;
}

void shared_observe(uint16_t s, uint8_t a, uint16_t s_next, uint32_t next_cell)
{
    const learner_config_t *c = &g_shared.cfg;
    uint32_t z3 = 3u * c->z_cells;
    uint32_t v3 = 3u * c->zdot_cells;
    uint32_t here = shared_state_cell(s);
    int32_t dv = (int32_t)(next_cell % v3) - (int32_t)(here % v3);
    int32_t dz = (int32_t)((next_cell / v3) % z3) - (int32_t)((here / v3) % z3);
    int32_t db = (int32_t)(next_cell / (v3 * z3)) - (int32_t)(here / (v3 * z3));
    uint8_t code = next_cell == SHARED_FAR_CELL ? (uint8_t)SHARED_FAR : offset_code(dz, dv, db);
    uint32_t t = type_of(s, a);
    record_type(t, code);
    if (g_shared.since_plan != NULL && g_shared.since_plan[t] < LEARNER_COUNT_MAX) {
        g_shared.since_plan[t]++;  /* after the count (and any halving), as record_shared */
    }
    if (g_shared.dirichlet) {
        record_local((uint32_t)s * LEARNER_ACTIONS + a, s_next);
    }
}

uint16_t shared_count(uint8_t a, uint16_t s, uint16_t s_next)
{
    /* The count the model gives (s, a, s'): the type's slots that shift s onto s' (and the local ones). */
    const shared_type_t *ty = &g_shared.types[type_of(s, a)];
    uint32_t n = 0u;
    for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
        if (ty->count[k] > 0u && shift(s, ty->code[k]) == s_next) {
            n += ty->count[k];
        }
    }
    if (g_shared.dirichlet) {
        uint32_t pair = (uint32_t)s * LEARNER_ACTIONS + a;
        const uint16_t *count = local_counts(pair);
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            uint32_t succ = g_shared.wide ? g_shared.local16[pair].succ[k] : g_shared.local8[pair].succ[k];
            if (count[k] > 0u && succ == s_next) {
                n += count[k];
            }
        }
    }
    return (uint16_t)(n > LEARNER_COUNT_MAX ? LEARNER_COUNT_MAX : n);
}

bool shared_tried(uint16_t s)
{
    return s < g_shared.terminal && (g_shared.types[type_of(s, 0u)].total > 0u || g_shared.types[type_of(s, 1u)].total > 0u);
}

uint32_t shared_evictions(void)
{
    uint32_t n = 0u;
    for (uint32_t t = 0u; t < types_of(&g_shared.cfg); t++) {
        n += g_shared.types[t].evictions;
    }
    return n;
}

uint16_t shared_slot(uint32_t t, uint32_t k, uint8_t *code)
{
    if (t >= types_of(&g_shared.cfg) || k >= SHARED_SLOTS) {
        return 0u;
    }
    *code = g_shared.types[t].code[k];
    return g_shared.types[t].count[k];
}

uint16_t shared_type_total(uint32_t t)
{
    return t < types_of(&g_shared.cfg) ? g_shared.types[t].total : 0u;
}

uint16_t shared_type_evictions(uint32_t t)
{
    return t < types_of(&g_shared.cfg) ? g_shared.types[t].evictions : 0u;
}

uint16_t shared_type_since_plan(uint32_t t)
{
    return g_shared.since_plan != NULL && t < types_of(&g_shared.cfg) ? g_shared.since_plan[t] : 0u;
}
