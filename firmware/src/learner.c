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
   arena holds shared.c's arrays instead (and every model, planning and inspection call goes there).
   This file: configuration, the arena, episodes, acting and inspection; the count model is learner_model.c,
   planning learner_plan.c. */
#include "learner.h"

#include <math.h>
#include <string.h>

#include "learner_internal.h"
#include "rng.h"
#include "shared.h"

#define STATE_INDEX_U8_LIMIT 256u  /* successor indices fit one byte up to this many states */
#define MAX_STATES 65535u          /* successor indices are uint16 */

/* Whole words, rounded up, so that a build's byte figure is always available. */
static uint32_t arena_words[(LEARNER_ARENA_BYTES + sizeof(uint32_t) - 1u) / sizeof(uint32_t)];

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
    return g_learner.used_bytes;
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
    if (!(c->filter_depth_gain >= 0.0f) || !(c->filter_velocity_gain >= 0.0f) || !(c->filter_bias_gain >= 0.0f)
        || !isfinite(c->filter_depth_gain) || !isfinite(c->filter_velocity_gain) || !isfinite(c->filter_bias_gain)
        || !isfinite(c->filter_accel_per_deg) || !isfinite(c->filter_drag_per_m)
        || (c->filter_depth_gain > 0.0f && c->vel_diff_steps > 0u)
        || (c->filter_depth_state && !(c->filter_depth_gain > 0.0f))) {
        return false;  /* the velocity filter or the depth difference, not both; its depth only with it (config.py) */
    }
    if (!(c->plan_loose_tolerance >= 0.0f) || !isfinite(c->plan_loose_tolerance)
        || (c->plan_stable_sweeps > 0u && !c->shared_model)) {
        return false;  /* the early planning stop is the shared model's (learning/config.py) */
    }
    if (!(c->plan_growth >= 0.0f && c->plan_growth <= 100.0f) || (c->plan_growth > 0.0f && !c->shared_model)) {
        return false;  /* planning on growth: in [0, 100], the shared model's (learning/config.py) */
    }
    if (!(c->fine_step_deg >= 0.0f) || !(c->fine_speed_mps >= 0.0f) || !(c->fine_reversal_deg >= 0.0f)
        || !isfinite(c->fine_step_deg) || !isfinite(c->fine_speed_mps) || !isfinite(c->fine_reversal_deg)) {
        return false;  /* learning/config.py: not negative */
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
    uint32_t s = g_learner.n_states;
    uint32_t cells = g_learner.n_pairs * g_learner.cfg.slots;
    uint32_t off = 0u;
    g_learner.reward_sum = (float *)(void *)(base + off);
    off += g_learner.n_pairs * (uint32_t)sizeof(float);
    g_learner.values = (float *)(void *)(base + off);
    off += s * (uint32_t)sizeof(float);
    if (g_learner.cfg.in_place_sweeps) {
        g_learner.new_values = g_learner.values;
    } else {
        g_learner.new_values = (float *)(void *)(base + off);
        off += s * (uint32_t)sizeof(float);
    }
    g_learner.succ_cnt = (uint16_t *)(void *)(base + off);
    off += cells * (uint32_t)sizeof(uint16_t);
    if (g_learner.wide_index) {
        g_learner.succ_idx8 = NULL;
        g_learner.succ_idx16 = (uint16_t *)(void *)(base + off);
        off += cells * (uint32_t)sizeof(uint16_t);
    } else {
        g_learner.succ_idx16 = NULL;
        g_learner.succ_idx8 = base + off;
        off += cells;
    }
    g_learner.policy = base + off;
    off += s;
    g_learner.used_bytes = off;
}

bool learner_configure(const learner_config_t *c)
{
    if (!config_valid(c) || learner_total_bytes(c) > learner_arena_bytes()) {
        return false;
    }
    g_learner.cfg = *c;
    g_learner.n_states = (uint16_t)states_of(c);
    g_learner.n_pairs = (uint32_t)g_learner.n_states * LEARNER_ACTIONS;
    g_learner.wide_index = g_learner.n_states > STATE_INDEX_U8_LIMIT;
    if (c->shared_model) {
        shared_carve((uint8_t *)arena_words, c);
        g_learner.used_bytes = shared_total_bytes(c);
    } else {
        carve_arena();
    }
    learner_reset();
    return true;
}

const learner_config_t *learner_config(void)
{
    return &g_learner.cfg;
}

void learner_seed(uint64_t seed)
{
    rng_seed(&g_learner.rng, seed);
}

/* ------------------------------------------------------------------ episodes and acting */

static float explore_probability(uint32_t episode)
{
    float frac = (float)episode / (float)g_learner.cfg.explore_decay_episodes;
    frac = frac < 1.0f ? frac : 1.0f;
    return g_learner.cfg.p_explore_start + (g_learner.cfg.p_explore_end - g_learner.cfg.p_explore_start) * frac;
}

void learner_reset(void)
{
    if (g_learner.n_states == 0u) {
        return;  /* never configured: nothing to forget */
    }
    memset(arena_words, 0, sizeof(arena_words));
    if (g_learner.cfg.shared_model) {
        shared_reset();
    }
    g_learner.episode = 0u;
    g_learner.p_explore = explore_probability(0u);
    g_learner.last_sweeps = 0u;
    /* As the Python learner: plan once on the empty model, which gives the tie-broken first policy. */
    learner_start_planning();
    while (!learner_plan_slice(g_learner.cfg.max_sweeps)) {
    }
}

void learner_end_episode(void)
{
    g_learner.episode++;
    g_learner.p_explore = explore_probability(g_learner.episode);
    if (g_learner.cfg.shared_model && !shared_plan_due()) {
        g_learner.last_sweeps = 0u;  /* planning on growth: the model has not grown enough, values and policy stay */
        return;
    }
    learner_start_planning();
}

uint32_t learner_episode(void)
{
    return g_learner.episode;
}

float learner_p_explore(void)
{
    return g_learner.p_explore;
}

uint16_t learner_n_states(void)
{
    return g_learner.n_states;
}

uint16_t learner_terminal(void)
{
    return learner_terminal_index();
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
    const learner_config_t *c = &g_learner.cfg;
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
        return g_learner.cfg.term_reward;
    }
    return -fabsf(depth_m - target_m);
}

uint8_t learner_act(uint16_t s)
{
    uint8_t action = learner_policy(s);
    if (action == SHARED_TIED) {
        action = rng_coin(&g_learner.rng) ? 1u : 0u;  /* ties_per_step: this draw comes first, as in Python */
    }
    uint64_t draw = rng_draw53(&g_learner.rng);
    uint64_t threshold = rng_scale53(g_learner.p_explore);
    bool explore = g_learner.cfg.explore_literal_gt ? draw > threshold : draw < threshold;
    return explore ? (uint8_t)(1u - action) : action;
}

float learner_step_deg(float velocity_mps, float plant_step_deg, bool reversal)
{
    const learner_config_t *c = &g_learner.cfg;
    if (c->fine_step_deg > 0.0f && fabsf(velocity_mps) < c->fine_speed_mps) {
        if (reversal && c->fine_reversal_deg > 0.0f) {
            return c->fine_reversal_deg;  /* a fine step after a reversal would spend itself in the gear's lash */
        }
        return c->fine_step_deg;  /* near a hover: chatter between the two actions costs a fraction of the step */
    }
    return plant_step_deg;
}

/* ------------------------------------------------------------------ inspection */

float learner_value(uint16_t s)
{
    if (g_learner.cfg.shared_model) {
        return shared_value(s);
    }
    return s < g_learner.n_states ? g_learner.values[s] : 0.0f;
}

uint8_t learner_policy(uint16_t s)
{
    if (g_learner.cfg.shared_model) {
        return shared_policy(s);
    }
    return s < g_learner.n_states ? g_learner.policy[s] : 0u;
}

float learner_q(uint16_t s, uint8_t a)
{
    if (g_learner.n_states == 0u || s >= learner_terminal() || a >= LEARNER_ACTIONS) {
        return 0.0f;
    }
    if (g_learner.cfg.shared_model) {
        return shared_q(s, a);
    }
    return learner_action_value((uint32_t)s * LEARNER_ACTIONS + a, g_learner.values);
}
