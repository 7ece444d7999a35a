/* The shared-model learner's model and planning (learning/shared.py in float), in learner.c's arena.

   Arena order: shared_type_t types[T], float values[S], float new_values[S] (Jacobi only),
   local counts[2 S] (Dirichlet only), uint8_t policy[ceil(S / 4)] (2 bits per state). Successors are
   shifted on the fly (Python precomputes rows once per plan); both give the same Q up to float32. */
#include "shared.h"

#include <math.h>
#include <string.h>

#define DZ_MAX 2
#define DV_MAX 8
#define DB_MAX 1
#define DV_SPAN (2 * DV_MAX + 1)
#define DB_SPAN (2 * DB_MAX + 1)
#define STATE_INDEX_U8_LIMIT 256u
#define POLICY_STATES_PER_BYTE 4u

_Static_assert(sizeof(shared_type_t) == 3u * SHARED_SLOTS + 4u, "the Teensy layout: 40 B per type");
_Static_assert(sizeof(shared_local8_t) == 3u * SHARED_SLOTS, "uint8 successor + uint16 count per slot");
_Static_assert(sizeof(shared_local16_t) == 4u * SHARED_SLOTS, "uint16 successor + uint16 count per slot");

static struct {
    learner_config_t cfg;
    uint32_t n_states;
    uint32_t terminal;
    bool dirichlet;
    bool wide;                 /* uint16 local successors */
    shared_type_t *types;
    float *values;
    float *new_values;         /* == values with in-place sweeps */
    shared_local8_t *local8;
    shared_local16_t *local16;
    uint8_t *policy;
    float z_reward[SHARED_MAX_Z_CELLS];  /* reward of arriving in each depth cell (cell_reward of learning) */
    /* planning in progress */
    uint32_t next_state;       /* where the current sweep resumes */
    float delta;               /* max |change| of the current sweep so far */
    uint32_t sweeps;
    bool planning;
    bool policy_pass;          /* values final: the policy is being derived, state by state */
} SH;

static uint32_t states_of(const learner_config_t *c)
{
    return (uint32_t)c->z_cells * c->zdot_cells * c->act_bins + 1u;
}

static uint32_t types_of(const learner_config_t *c)
{
    return (uint32_t)c->zdot_cells * c->act_bins * LEARNER_ACTIONS;
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

uint32_t shared_total_bytes(const learner_config_t *c)
{
    uint32_t sweep_buffer = c->in_place_sweeps ? 0u : states_of(c) * (uint32_t)sizeof(float);
    return shared_memory_bytes(c) + sweep_buffer + policy_bytes(states_of(c));
}

void shared_carve(uint8_t *base, const learner_config_t *c)
{
    SH.cfg = *c;
    SH.n_states = states_of(c);
    SH.terminal = SH.n_states - 1u;
    SH.dirichlet = c->dirichlet_w > 0.0f;
    SH.wide = SH.n_states > STATE_INDEX_U8_LIMIT;
    uint32_t off = 0u;
    SH.types = (shared_type_t *)(void *)(base + off);
    off += types_of(c) * (uint32_t)sizeof(shared_type_t);
    SH.values = (float *)(void *)(base + off);
    off += SH.n_states * (uint32_t)sizeof(float);
    SH.new_values = SH.values;
    if (!c->in_place_sweeps) {
        SH.new_values = (float *)(void *)(base + off);
        off += SH.n_states * (uint32_t)sizeof(float);
    }
    SH.local8 = NULL;
    SH.local16 = NULL;
    if (SH.dirichlet && SH.wide) {
        SH.local16 = (shared_local16_t *)(void *)(base + off);
    } else if (SH.dirichlet) {
        SH.local8 = (shared_local8_t *)(void *)(base + off);
    }
    off += local_bytes(c);
    SH.policy = base + off;
    /* learning.shared.cell_reward: minus the distance of the depth cell's centre from the target. */
    for (uint32_t iz = 0u; iz < c->z_cells && iz < SHARED_MAX_Z_CELLS; iz++) {
        SH.z_reward[iz] = -fabsf(-c->z_tol_m + ((float)iz + 0.5f) * 2.0f * c->z_tol_m / (float)c->z_cells);
    }
    SH.planning = false;
    SH.sweeps = 0u;
}

void shared_reset(void)
{
    SH.planning = false;
    SH.sweeps = 0u;
}

/* ------------------------------------------------------------------ grid codes */

static uint32_t type_of(uint32_t s, uint8_t a)
{
    const learner_config_t *c = &SH.cfg;
    uint32_t iv = s % c->zdot_cells;
    uint32_t ib = s / ((uint32_t)c->zdot_cells * c->z_cells);
    return (ib * c->zdot_cells + iv) * LEARNER_ACTIONS + a;
}

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
    const learner_config_t *c = &SH.cfg;
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
    const learner_config_t *c = &SH.cfg;
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

/* learning.shared._shift: the successor of s under an offset code, terminal when it leaves the region. */
static uint32_t shift(uint32_t s, uint8_t code)
{
    const learner_config_t *c = &SH.cfg;
    if (code == SHARED_FAR) {
        return SH.terminal;
    }
    int32_t db = (int32_t)(code % DB_SPAN) - DB_MAX;
    int32_t dv = (int32_t)((code / DB_SPAN) % DV_SPAN) - DV_MAX;
    int32_t dz = (int32_t)(code / (DB_SPAN * DV_SPAN)) - DZ_MAX;
    int32_t iv = (int32_t)(s % c->zdot_cells) + dv;
    int32_t iz = (int32_t)((s / c->zdot_cells) % c->z_cells) + dz;
    int32_t ib = (int32_t)(s / ((uint32_t)c->zdot_cells * c->z_cells)) + db;
    ib = ib < 0 ? 0 : ib > (int32_t)c->act_bins - 1 ? (int32_t)c->act_bins - 1 : ib;
    if (iz < 0 || iz >= (int32_t)c->z_cells) {
        return SH.terminal;
    }
    if (iv < 0 || iv >= (int32_t)c->zdot_cells) {
        if (!c->depth_only_terminal) {
            return SH.terminal;
        }
        iv = iv < 0 ? 0 : (int32_t)c->zdot_cells - 1;
    }
    return ((uint32_t)ib * c->z_cells + (uint32_t)iz) * c->zdot_cells + (uint32_t)iv;
}

static float cell_reward(uint32_t s)
{
    if (s == SH.terminal) {
        return SH.cfg.term_reward;
    }
    return SH.z_reward[(s / SH.cfg.zdot_cells) % SH.cfg.z_cells];
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
    shared_type_t *ty = &SH.types[t];
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

static uint16_t *local_counts(uint32_t pair)
{
    return SH.wide ? SH.local16[pair].count : SH.local8[pair].count;
}

/* learning.model.record_transition on the local slots (the reward sums are not kept: unused). */
static void record_local(uint32_t pair, uint32_t s_next)
{
    uint16_t *count = local_counts(pair);
    const void *keys = SH.wide ? (const void *)SH.local16[pair].succ : (const void *)SH.local8[pair].succ;
    bool evict = false;
    uint32_t slot = find_slot(count, s_next, SH.wide, keys, &evict);
    if (evict || count[slot] == 0u) {
        count[slot] = 0u;
        if (SH.wide) {
            SH.local16[pair].succ[slot] = (uint16_t)s_next;
        } else {
            SH.local8[pair].succ[slot] = (uint8_t)s_next;
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
    const learner_config_t *c = &SH.cfg;
    uint32_t z3 = 3u * c->z_cells;
    uint32_t v3 = 3u * c->zdot_cells;
    uint32_t here = shared_state_cell(s);
    int32_t dv = (int32_t)(next_cell % v3) - (int32_t)(here % v3);
    int32_t dz = (int32_t)((next_cell / v3) % z3) - (int32_t)((here / v3) % z3);
    int32_t db = (int32_t)(next_cell / (v3 * z3)) - (int32_t)(here / (v3 * z3));
    uint8_t code = next_cell == SHARED_FAR_CELL ? (uint8_t)SHARED_FAR : offset_code(dz, dv, db);
    record_type(type_of(s, a), code);
    if (SH.dirichlet) {
        record_local((uint32_t)s * LEARNER_ACTIONS + a, s_next);
    }
}

uint16_t shared_count(uint8_t a, uint16_t s, uint16_t s_next)
{
    /* The count the model gives (s, a, s'): the type's slots that shift s onto s' (and the local ones). */
    const shared_type_t *ty = &SH.types[type_of(s, a)];
    uint32_t n = 0u;
    for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
        if (ty->count[k] > 0u && shift(s, ty->code[k]) == s_next) {
            n += ty->count[k];
        }
    }
    if (SH.dirichlet) {
        uint32_t pair = (uint32_t)s * LEARNER_ACTIONS + a;
        const uint16_t *count = local_counts(pair);
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            uint32_t succ = SH.wide ? SH.local16[pair].succ[k] : SH.local8[pair].succ[k];
            if (count[k] > 0u && succ == s_next) {
                n += count[k];
            }
        }
    }
    return (uint16_t)(n > LEARNER_COUNT_MAX ? LEARNER_COUNT_MAX : n);
}

bool shared_tried(uint16_t s)
{
    return s < SH.terminal && (SH.types[type_of(s, 0u)].total > 0u || SH.types[type_of(s, 1u)].total > 0u);
}

uint32_t shared_evictions(void)
{
    uint32_t n = 0u;
    for (uint32_t t = 0u; t < types_of(&SH.cfg); t++) {
        n += SH.types[t].evictions;
    }
    return n;
}

uint16_t shared_slot(uint32_t t, uint32_t k, uint8_t *code)
{
    if (t >= types_of(&SH.cfg) || k >= SHARED_SLOTS) {
        return 0u;
    }
    *code = SH.types[t].code[k];
    return SH.types[t].count[k];
}

uint16_t shared_type_total(uint32_t t)
{
    return t < types_of(&SH.cfg) ? SH.types[t].total : 0u;
}

uint16_t shared_type_evictions(uint32_t t)
{
    return t < types_of(&SH.cfg) ? SH.types[t].evictions : 0u;
}

/* ------------------------------------------------------------------ Q and planning */

/* learning.shared.compile_shared_rows and planning._action_value for one pair, in float, same order. */
static float action_value(uint32_t s, uint8_t a, const float *values)
{
    const learner_config_t *c = &SH.cfg;
    const shared_type_t *ty = &SH.types[type_of(s, a)];
    uint32_t pair = s * LEARNER_ACTIONS + a;
    float shared_total = (float)ty->total;
    float local_total = 0.0f;
    const uint16_t *local = NULL;
    if (SH.dirichlet) {
        local = local_counts(pair);
        uint32_t n = 0u;
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            n += local[k];
        }
        local_total = (float)n;
    }
    float n = shared_total + local_total;
    if (!(n >= (float)c->known_count)) {
        return c->untried_q;
    }
    float w_local = 0.0f;
    float w_shared = 0.0f;
    if (local_total > 0.0f && shared_total > 0.0f) {
        w_local = 1.0f / (local_total + c->dirichlet_w);
        w_shared = c->dirichlet_w / (local_total + c->dirichlet_w) / shared_total;
    } else if (local_total > 0.0f) {
        w_local = 1.0f / local_total;
    } else if (shared_total > 0.0f) {
        w_shared = 1.0f / shared_total;
    }
    float reward = 0.0f;
    float expected = 0.0f;
    if (w_shared > 0.0f) {
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            if (ty->count[k] > 0u) {
                uint32_t nxt = shift(s, ty->code[k]);
                float p = (float)ty->count[k] * w_shared;
                reward += p * cell_reward(nxt);
                expected += p * values[nxt];
            }
        }
    }
    if (local != NULL) {
        for (uint32_t k = 0u; k < SHARED_SLOTS; k++) {
            if (local[k] > 0u) {
                uint32_t nxt = SH.wide ? SH.local16[pair].succ[k] : SH.local8[pair].succ[k];
                float p = (float)local[k] * w_local;
                reward += p * cell_reward(nxt);
                expected += p * values[nxt];
            }
        }
    }
    if (c->count_bonus > 0.0f) {
        reward += c->count_bonus / sqrtf(n);
    }
    return reward + c->gamma * expected;
}

void shared_start_planning(void)
{
    SH.values[SH.terminal] = 0.0f;
    if (!SH.cfg.in_place_sweeps) {
        memcpy(SH.new_values, SH.values, (size_t)SH.n_states * sizeof(float));
    }
    SH.next_state = 0u;
    SH.delta = 0.0f;
    SH.sweeps = 0u;
    SH.planning = true;
    SH.policy_pass = false;
}

static void set_policy(uint32_t s, uint8_t p)
{
    uint32_t shift_bits = 2u * (s % POLICY_STATES_PER_BYTE);
    uint8_t *byte = &SH.policy[s / POLICY_STATES_PER_BYTE];
    *byte = (uint8_t)((*byte & ~(3u << shift_bits)) | ((uint32_t)p << shift_bits));
}

/* planning.plan_rows' policy for state s: argmax of Q from the final values, a tie TIED or drawn (the
   states in order, so the draws are Python's). */
static void derive_policy(uint32_t s, rng_t *rng)
{
    const learner_config_t *c = &SH.cfg;
    float d = 0.0f;
    if (s != SH.terminal) {
        d = action_value(s, 1u, SH.values) - action_value(s, 0u, SH.values);
        d = c->policy_argmin ? -d : d;
    }
    uint8_t p = 0u;
    if (d > 0.0f) {
        p = 1u;
    } else if (d < 0.0f) {
        p = 0u;
    } else if (c->random_ties && c->ties_per_step) {
        p = (uint8_t)SHARED_TIED;
    } else {
        p = (uint8_t)(c->random_ties && rng_coin(rng) ? 1u : 0u);
    }
    set_policy(s, p);
}

bool shared_plan_backups(uint32_t max_backups, rng_t *rng)
{
    if (!SH.planning) {
        return true;
    }
    for (uint32_t i = 0u; i < max_backups; i++) {
        uint32_t s = SH.next_state;
        if (SH.policy_pass) {
            /* The policy costs what a backup does (two Q values per state): sliced the same way. */
            derive_policy(s, rng);
            SH.next_state++;
            if (SH.next_state == SH.n_states) {
                SH.planning = false;
                return true;
            }
            continue;
        }
        float best = action_value(s, 0u, SH.values);
        float q1 = action_value(s, 1u, SH.values);
        best = q1 > best ? q1 : best;
        float change = fabsf(best - SH.values[s]);
        SH.delta = change > SH.delta ? change : SH.delta;
        SH.new_values[s] = best;  /* the same array with in-place sweeps */
        SH.next_state++;
        if (SH.next_state < SH.terminal) {
            continue;
        }
        /* A sweep is complete. */
        if (!SH.cfg.in_place_sweeps) {
            memcpy(SH.values, SH.new_values, (size_t)SH.terminal * sizeof(float));
        }
        SH.sweeps++;
        bool converged = SH.delta < SH.cfg.vi_tol;
        SH.next_state = 0u;
        SH.delta = 0.0f;
        if (converged || SH.sweeps >= SH.cfg.max_sweeps) {
            SH.policy_pass = true;  /* the policy of the plan in progress is final only when this pass ends */
        }
    }
    return false;
}

uint32_t shared_sweeps(void)
{
    return SH.sweeps;
}

float shared_value(uint16_t s)
{
    return s < SH.n_states ? SH.values[s] : 0.0f;
}

uint8_t shared_policy(uint16_t s)
{
    if (s >= SH.n_states) {
        return 0u;
    }
    return (uint8_t)((SH.policy[s / POLICY_STATES_PER_BYTE] >> (2u * (s % POLICY_STATES_PER_BYTE))) & 3u);
}

float shared_q(uint16_t s, uint8_t a)
{
    if (s >= SH.terminal || a >= LEARNER_ACTIONS) {
        return 0.0f;
    }
    return action_value(s, a, SH.values);
}
