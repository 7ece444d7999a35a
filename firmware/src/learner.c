/* The model-based learner of paper Section III over the sparse slot model, in one static arena.

   The arena holds, for S states and P = 2 S (state, action) pairs, in this order (each array starts
   aligned for its type without padding, so the sizes add up exactly):
     float    reward_sum[P]          reward sum per pair
     float    values[S]              v, terminal last (always 0)
     float    new_values[S]          Jacobi sweep buffer (absent with in-place sweeps)
     uint16_t succ_cnt[P][slots]     transition counts per successor slot
     uint8_t  succ_idx[P][slots]     successor state per slot (uint16_t past 256 states)
     uint8_t  policy[S]
   reward_sum, succ_cnt and succ_idx are the model (learning's model_memory_bytes); with values and
   policy they make learning's learner_memory_bytes; the sweep buffer comes on top. With shared_model the
   arena holds shared.c's arrays instead (and every model, planning and inspection call goes there). */
#include "learner.h"

#include <math.h>
#include <string.h>

#include "rng.h"
#include "shared.h"

#define STATE_INDEX_U8_LIMIT 256u  /* successor indices fit one byte up to this many states */
#define MAX_STATES 65535u          /* successor indices are uint16 */

/* Whole words, rounded up, so that a build's byte figure is always available. */
static uint32_t arena_words[(LEARNER_ARENA_BYTES + sizeof(uint32_t) - 1u) / sizeof(uint32_t)];

static struct {
    learner_config_t cfg;
    uint16_t n_states;
    uint32_t n_pairs;
    bool wide_index;            /* uint16 successor indices */
    float *reward_sum;
    float *values;
    float *new_values;          /* == values with in-place sweeps */
    uint16_t *succ_cnt;
    uint8_t *succ_idx8;
    uint16_t *succ_idx16;
    uint8_t *policy;
    rng_t rng;
    uint32_t episode;
    float p_explore;
    bool planning;
    uint32_t sweeps;            /* of the planning run in progress */
    uint32_t last_sweeps;
    uint32_t used_bytes;        /* end of the carved arrays */
} L;

/* ------------------------------------------------------------------ configuration and memory */

void learner_default_config(learner_config_t *c)
{
    memset(c, 0, sizeof(*c));
    c->z_cells = 10u;
    c->zdot_cells = 10u;
    c->act_bins = 1u;
    c->slots = 12u;
    c->z_tol_m = 0.1f;
    c->zdot_tol_mps = 0.04f;
    c->gamma = 0.99f;
    c->vi_tol = 1e-4f;
    c->term_reward = -10.0f;
    c->p_explore_start = 0.10f;
    c->p_explore_end = 0.0f;
    c->explore_decay_episodes = 1000u;
    c->untried_q = 0.0f;
    c->known_count = 1u;
    c->random_ties = true;
    c->max_sweeps = 100000u;
}

static uint32_t states_of(const learner_config_t *c)
{
    return (uint32_t)c->z_cells * c->zdot_cells * c->act_bins + 1u;
}

static uint32_t model_bytes(const learner_config_t *c)
{
    uint32_t pairs = states_of(c) * LEARNER_ACTIONS;
    uint32_t index_bytes = states_of(c) <= STATE_INDEX_U8_LIMIT ? 1u : 2u;
    return pairs * c->slots * (index_bytes + (uint32_t)sizeof(uint16_t)) + pairs * (uint32_t)sizeof(float);
}

uint32_t learner_memory_bytes(const learner_config_t *c)
{
    if (c->shared_model) {
        return shared_memory_bytes(c);
    }
    return model_bytes(c) + states_of(c) * ((uint32_t)sizeof(float) + (uint32_t)sizeof(uint8_t));
}

uint32_t learner_total_bytes(const learner_config_t *c)
{
    if (c->shared_model) {
        return shared_total_bytes(c);
    }
    return learner_memory_bytes(c) + (c->in_place_sweeps ? 0u : states_of(c) * (uint32_t)sizeof(float));
}

uint32_t learner_used_bytes(void)
{
    return L.used_bytes;
}

uint32_t learner_arena_bytes(void)
{
    return (uint32_t)sizeof(arena_words);
}

static bool config_valid(const learner_config_t *c)
{
    if (c->z_cells < 1u || c->zdot_cells < 1u || c->act_bins < 1u || c->slots < 1u || c->known_count < 1u) {
        return false;
    }
    if (states_of(c) > MAX_STATES || c->explore_decay_episodes < 1u || c->max_sweeps < 1u) {
        return false;
    }
    if (c->shared_model && (c->slots != SHARED_SLOTS || c->z_cells > SHARED_MAX_Z_CELLS
                            || c->zdot_cells > SHARED_MAX_ZDOT_CELLS)) {
        return false;  /* the shared layout has SHARED_SLOTS slots per type, a reward per depth and velocity cell */
    }
    if (!(c->dirichlet_w >= 0.0f) || !(c->count_bonus >= 0.0f) || !(c->vel_penalty >= 0.0f)
        || !isfinite(c->dirichlet_w) || !isfinite(c->count_bonus) || !isfinite(c->vel_penalty)) {
        return false;
    }
    /* Written so that NaN fails every test. */
    if (!(c->z_tol_m > 0.0f) || !(c->zdot_tol_mps > 0.0f) || !(c->vi_tol > 0.0f)) {
        return false;
    }
    if (!(c->gamma >= 0.0f && c->gamma < 1.0f)) {
        return false;
    }
    if (!(c->p_explore_start >= 0.0f && c->p_explore_start <= 1.0f)
        || !(c->p_explore_end >= 0.0f && c->p_explore_end <= 1.0f)) {
        return false;
    }
    return isfinite(c->term_reward) && isfinite(c->untried_q);
}

static void carve_arena(void)
{
    uint8_t *base = (uint8_t *)arena_words;
    uint32_t s = L.n_states;
    uint32_t cells = L.n_pairs * L.cfg.slots;
    uint32_t off = 0u;
    L.reward_sum = (float *)(void *)(base + off);
    off += L.n_pairs * (uint32_t)sizeof(float);
    L.values = (float *)(void *)(base + off);
    off += s * (uint32_t)sizeof(float);
    if (L.cfg.in_place_sweeps) {
        L.new_values = L.values;
    } else {
        L.new_values = (float *)(void *)(base + off);
        off += s * (uint32_t)sizeof(float);
    }
    L.succ_cnt = (uint16_t *)(void *)(base + off);
    off += cells * (uint32_t)sizeof(uint16_t);
    if (L.wide_index) {
        L.succ_idx8 = NULL;
        L.succ_idx16 = (uint16_t *)(void *)(base + off);
        off += cells * (uint32_t)sizeof(uint16_t);
    } else {
        L.succ_idx16 = NULL;
        L.succ_idx8 = base + off;
        off += cells;
    }
    L.policy = base + off;
    off += s;
    L.used_bytes = off;
}

bool learner_configure(const learner_config_t *c)
{
    if (!config_valid(c) || learner_total_bytes(c) > learner_arena_bytes()) {
        return false;
    }
    L.cfg = *c;
    L.n_states = (uint16_t)states_of(c);
    L.n_pairs = (uint32_t)L.n_states * LEARNER_ACTIONS;
    L.wide_index = L.n_states > STATE_INDEX_U8_LIMIT;
    if (c->shared_model) {
        shared_carve((uint8_t *)arena_words, c);
        L.used_bytes = shared_total_bytes(c);
    } else {
        carve_arena();
    }
    learner_reset();
    return true;
}

const learner_config_t *learner_config(void)
{
    return &L.cfg;
}

void learner_seed(uint64_t seed)
{
    rng_seed(&L.rng, seed);
}

/* ------------------------------------------------------------------ the count model (Alg. 3) */

static uint16_t succ_get(uint32_t cell)
{
    return L.wide_index ? L.succ_idx16[cell] : L.succ_idx8[cell];
}

static void succ_set(uint32_t cell, uint16_t s_next)
{
    if (L.wide_index) {
        L.succ_idx16[cell] = s_next;
    } else {
        L.succ_idx8[cell] = (uint8_t)s_next;
    }
}

static uint32_t row_total(uint32_t row)
{
    const uint16_t *cnt = &L.succ_cnt[row * L.cfg.slots];
    uint32_t total = 0u;
    for (uint32_t k = 0u; k < L.cfg.slots; k++) {
        total += cnt[k];
    }
    return total;
}

uint32_t learner_cell(float depth_m, float velocity_mps, float target_m, float actuator_fraction)
{
    return L.cfg.shared_model ? shared_raw_cell(depth_m, velocity_mps, target_m, actuator_fraction) : 0u;
}

uint32_t learner_evictions(void)
{
    return L.cfg.shared_model && L.n_states != 0u ? shared_evictions() : 0u;
}

void learner_observe_cell(uint16_t s, uint8_t a, float reward, uint16_t s_next, uint32_t next_cell)
{
    if (L.n_states == 0u || s >= learner_terminal() || a >= LEARNER_ACTIONS || s_next >= L.n_states) {
        return;
    }
    if (L.cfg.shared_model) {
        shared_observe(s, a, s_next, next_cell);
        return;
    }
    learner_observe(s, a, reward, s_next);
}

void learner_observe(uint16_t s, uint8_t a, float reward, uint16_t s_next)
{
    if (L.n_states == 0u || s >= learner_terminal() || a >= LEARNER_ACTIONS || s_next >= L.n_states) {
        return;
    }
    if (L.cfg.shared_model) {
        /* the cell of a live successor is its own; a terminal one lies out of reach */
        shared_observe(s, a, s_next, s_next == learner_terminal() ? SHARED_FAR_CELL : shared_state_cell(s_next));
        return;
    }
    uint32_t row = (uint32_t)s * LEARNER_ACTIONS + a;
    uint32_t first = row * L.cfg.slots;
    uint16_t *cnt = &L.succ_cnt[first];
    int32_t slot = -1;
    int32_t free_slot = -1;
    for (uint32_t k = 0u; k < L.cfg.slots; k++) {
        if (cnt[k] > 0u) {
            if (succ_get(first + k) == s_next) {
                slot = (int32_t)k;
                break;
            }
        } else if (free_slot < 0) {
            free_slot = (int32_t)k;
        }
    }
    if (slot < 0) {
        if (free_slot < 0) {
            /* All slots taken: forget the rarest successor, keeping the mean reward unchanged. */
            free_slot = 0;
            for (uint32_t k = 1u; k < L.cfg.slots; k++) {
                if (cnt[k] < cnt[free_slot]) {
                    free_slot = (int32_t)k;
                }
            }
            uint32_t total = row_total(row);
            uint32_t kept = total - cnt[free_slot];
            L.reward_sum[row] *= (float)kept / (float)total;
            cnt[free_slot] = 0u;
        }
        slot = free_slot;
        succ_set(first + (uint32_t)slot, s_next);
    }
    if (cnt[slot] == LEARNER_COUNT_MAX) {
        /* Saturation: halve the row (rounding up keeps every seen successor); proportions survive. */
        uint32_t total = row_total(row);
        for (uint32_t k = 0u; k < L.cfg.slots; k++) {
            cnt[k] = (uint16_t)((cnt[k] + 1u) / 2u);
        }
        L.reward_sum[row] *= (float)row_total(row) / (float)total;
    }
    cnt[slot]++;
    L.reward_sum[row] += reward;
}

uint16_t learner_count(uint8_t a, uint16_t s, uint16_t s_next)
{
    if (s >= L.n_states || a >= LEARNER_ACTIONS) {
        return 0u;
    }
    if (L.cfg.shared_model) {
        return s < learner_terminal() && s_next < L.n_states ? shared_count(a, s, s_next) : 0u;
    }
    uint32_t first = ((uint32_t)s * LEARNER_ACTIONS + a) * L.cfg.slots;
    for (uint32_t k = 0u; k < L.cfg.slots; k++) {
        if (L.succ_cnt[first + k] > 0u && succ_get(first + k) == s_next) {
            return L.succ_cnt[first + k];
        }
    }
    return 0u;
}

bool learner_tried(uint16_t s)
{
    if (s >= learner_terminal()) {
        return false;
    }
    if (L.cfg.shared_model) {
        return shared_tried(s);
    }
    return row_total((uint32_t)s * LEARNER_ACTIONS) > 0u || row_total((uint32_t)s * LEARNER_ACTIONS + 1u) > 0u;
}

/* ------------------------------------------------------------------ planning (Alg. 4, fixed), sliced */

/* Q of one pair from the model and the given values (planning.py _action_value). */
static float action_value(uint32_t row, const float *values)
{
    const uint16_t *cnt = &L.succ_cnt[row * L.cfg.slots];
    uint32_t first = row * L.cfg.slots;
    uint32_t total = 0u;
    float weighted = 0.0f;
    for (uint32_t k = 0u; k < L.cfg.slots; k++) {
        if (cnt[k] > 0u) {
            total += cnt[k];
            weighted += (float)cnt[k] * values[succ_get(first + k)];
        }
    }
    bool known = L.cfg.alg4_printed ? total > 0u : total >= L.cfg.known_count;
    if (!known) {
        return L.cfg.alg4_printed ? 0.0f : L.cfg.untried_q;
    }
    /* One division per row instead of one per slot: sum_k (c_k / N) v_k = (sum_k c_k v_k) / N. The
       printed form's row sum of P is 1 for a tried row, so it equals the standard backup here. */
    float n = (float)total;
    return L.reward_sum[row] / n + L.cfg.gamma * (weighted / n);
}

static void start_planning(void)
{
    if (L.n_states == 0u) {
        return;  /* never configured */
    }
    if (L.cfg.shared_model) {
        shared_start_planning();
        L.planning = true;
        return;
    }
    uint16_t terminal = learner_terminal();
    L.values[terminal] = 0.0f;
    if (!L.cfg.in_place_sweeps) {
        memcpy(L.new_values, L.values, (size_t)L.n_states * sizeof(float));
    }
    L.sweeps = 0u;
    L.planning = true;
}

/* One sweep; returns true when max |change| fell below the tolerance. */
static bool sweep(void)
{
    uint16_t terminal = learner_terminal();
    float delta = 0.0f;
    for (uint32_t s = 0u; s < terminal; s++) {
        float best = -INFINITY;
        for (uint32_t a = 0u; a < LEARNER_ACTIONS; a++) {
            float q = action_value(s * LEARNER_ACTIONS + a, L.values);
            best = q > best ? q : best;
        }
        float change = fabsf(best - L.values[s]);
        delta = change > delta ? change : delta;
        L.new_values[s] = best;  /* the same array with in-place sweeps */
    }
    if (!L.cfg.in_place_sweeps) {
        memcpy(L.values, L.new_values, (size_t)terminal * sizeof(float));
    }
    L.sweeps++;
    return delta < L.cfg.vi_tol;
}

/* The greedy policy from the converged values; exact ties at random (one draw per tie, states in order,
   as planning.py, so the same stream gives the same policy). */
static void finish_planning(void)
{
    uint16_t terminal = learner_terminal();
    for (uint32_t s = 0u; s < L.n_states; s++) {
        float d = 0.0f;
        if (s != terminal) {
            d = action_value(s * LEARNER_ACTIONS + 1u, L.values) - action_value(s * LEARNER_ACTIONS, L.values);
            d = L.cfg.policy_argmin ? -d : d;
        }
        if (d > 0.0f) {
            L.policy[s] = 1u;
        } else if (d < 0.0f) {
            L.policy[s] = 0u;
        } else if (L.cfg.random_ties && L.cfg.ties_per_step) {
            L.policy[s] = (uint8_t)SHARED_TIED;  /* drawn at every step by learner_act */
        } else {
            L.policy[s] = (uint8_t)(L.cfg.random_ties && rng_coin(&L.rng) ? 1u : 0u);
        }
    }
    L.last_sweeps = L.sweeps;
    L.planning = false;
}

static bool shared_done(bool done)
{
    if (done) {
        L.planning = false;
        L.last_sweeps = shared_sweeps();
    }
    return done;
}

bool learner_plan_slice(uint32_t max_sweeps)
{
    if (!L.planning) {
        return true;
    }
    if (L.cfg.shared_model) {
        uint32_t sweep = learner_terminal();
        for (uint32_t i = 0u; i < max_sweeps; i++) {
            if (shared_done(shared_plan_backups(sweep, &L.rng))) {
                return true;
            }
        }
        return false;
    }
    for (uint32_t i = 0u; i < max_sweeps; i++) {
        if (sweep() || L.sweeps >= L.cfg.max_sweeps) {
            finish_planning();
            return true;
        }
    }
    return false;
}

bool learner_plan_backups(uint32_t max_backups)
{
    if (!L.planning) {
        return true;
    }
    if (L.cfg.shared_model) {
        return shared_done(shared_plan_backups(max_backups, &L.rng));
    }
    uint32_t sweep = learner_terminal() > 0u ? learner_terminal() : 1u;
    return learner_plan_slice((max_backups + sweep - 1u) / sweep);
}

bool learner_planning(void)
{
    return L.planning;
}

uint32_t learner_last_sweeps(void)
{
    return L.last_sweeps;
}

/* ------------------------------------------------------------------ episodes and acting */

static float explore_probability(uint32_t episode)
{
    float frac = (float)episode / (float)L.cfg.explore_decay_episodes;
    frac = frac < 1.0f ? frac : 1.0f;
    return L.cfg.p_explore_start + (L.cfg.p_explore_end - L.cfg.p_explore_start) * frac;
}

void learner_reset(void)
{
    if (L.n_states == 0u) {
        return;  /* never configured: nothing to forget */
    }
    memset(arena_words, 0, sizeof(arena_words));
    if (L.cfg.shared_model) {
        shared_reset();
    }
    L.episode = 0u;
    L.p_explore = explore_probability(0u);
    L.last_sweeps = 0u;
    /* As the Python learner: plan once on the empty model, which gives the tie-broken first policy. */
    start_planning();
    while (!learner_plan_slice(L.cfg.max_sweeps)) {
    }
}

void learner_end_episode(void)
{
    L.episode++;
    L.p_explore = explore_probability(L.episode);
    start_planning();
}

uint32_t learner_episode(void)
{
    return L.episode;
}

float learner_p_explore(void)
{
    return L.p_explore;
}

uint16_t learner_n_states(void)
{
    return L.n_states;
}

uint16_t learner_terminal(void)
{
    return (uint16_t)(L.n_states - 1u);
}

static uint32_t cell_of(float x, float half_width, uint8_t cells)
{
    float i = floorf((x + half_width) / (2.0f * half_width) * (float)cells);
    if (!(i > 0.0f)) {
        return 0u;
    }
    return i >= (float)cells ? cells - 1u : (uint32_t)i;
}

uint16_t learner_state(float depth_m, float velocity_mps, float target_m, float actuator_fraction)
{
    const learner_config_t *c = &L.cfg;
    float error_m = depth_m - target_m;
    if (!(fabsf(error_m) < c->z_tol_m)) {
        return learner_terminal();
    }
    if (!c->depth_only_terminal && !(fabsf(velocity_mps) < c->zdot_tol_mps)) {
        return learner_terminal();
    }
    uint32_t iz = cell_of(error_m, c->z_tol_m, c->z_cells);
    /* With the depth-only terminal the outer velocity cells are open-ended (clipped). */
    uint32_t iv = cell_of(velocity_mps, c->zdot_tol_mps, c->zdot_cells);
    uint32_t ib = c->act_bins > 1u ? cell_of(actuator_fraction, 1.0f, c->act_bins) : 0u;
    return (uint16_t)((ib * c->z_cells + iz) * c->zdot_cells + iv);
}

float learner_reward(float depth_m, float target_m, uint16_t s_next)
{
    if (s_next == learner_terminal()) {
        return L.cfg.term_reward;
    }
    return -fabsf(depth_m - target_m);
}

uint8_t learner_act(uint16_t s)
{
    uint8_t action = learner_policy(s);
    if (action == SHARED_TIED) {
        action = rng_coin(&L.rng) ? 1u : 0u;  /* ties_per_step: this draw comes first, as in Python */
    }
    uint64_t draw = rng_draw53(&L.rng);
    uint64_t threshold = rng_scale53(L.p_explore);
    bool explore = L.cfg.explore_literal_gt ? draw > threshold : draw < threshold;
    return explore ? (uint8_t)(1u - action) : action;
}

/* ------------------------------------------------------------------ inspection */

float learner_value(uint16_t s)
{
    if (L.cfg.shared_model) {
        return shared_value(s);
    }
    return s < L.n_states ? L.values[s] : 0.0f;
}

uint8_t learner_policy(uint16_t s)
{
    if (L.cfg.shared_model) {
        return shared_policy(s);
    }
    return s < L.n_states ? L.policy[s] : 0u;
}

float learner_q(uint16_t s, uint8_t a)
{
    if (L.n_states == 0u || s >= learner_terminal() || a >= LEARNER_ACTIONS) {
        return 0.0f;
    }
    if (L.cfg.shared_model) {
        return shared_q(s, a);
    }
    return action_value((uint32_t)s * LEARNER_ACTIONS + a, L.values);
}
