/* The shared-model learner's Q and planning (learning/shared.py and learning/planning.py in float): sliced
   value iteration, then the policy. Successors are shifted on the fly (Python precomputes rows once per plan);
   both give the same Q up to float32. */
#include "shared_internal.h"

#include <math.h>
#include <string.h>

/* ------------------------------------------------------------------ Q and planning */

/* learning.shared.compile_shared_rows and planning._action_value for one pair, in float, same order. */
static float action_value(uint32_t s, uint8_t a, const float *values)
{
    const learner_config_t *c = &g_shared.cfg;
    const shared_type_t *ty = &g_shared.types[type_of(s, a)];
    uint32_t pair = s * LEARNER_ACTIONS + a;
    float shared_total = (float)ty->total;
    float local_total = 0.0f;
    const uint16_t *local = NULL;
    if (g_shared.dirichlet) {
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
                uint32_t nxt = g_shared.wide ? g_shared.local16[pair].succ[k] : g_shared.local8[pair].succ[k];
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

bool shared_plan_due(void)
{
    if (g_shared.since_plan == NULL) {
        return true;  /* plan_growth 0: a plan after every episode */
    }
    for (uint32_t t = 0u; t < types_of(&g_shared.cfg); t++) {
        uint32_t n = g_shared.since_plan[t];
        uint32_t total = g_shared.types[t].total;
        /* What the type had at the last plan; at least 1, and so when halving or evictions took it below n. */
        uint32_t before = total > n + 1u ? total - n : 1u;
        if (n > 0u && (double)n >= (double)g_shared.cfg.plan_growth * (double)before) {
            return true;
        }
    }
    return false;
}

void shared_start_planning(void)
{
    if (g_shared.since_plan != NULL) {
        memset(g_shared.since_plan, 0, (size_t)types_of(&g_shared.cfg) * sizeof(uint16_t));
    }
    g_shared.values[g_shared.terminal] = 0.0f;
    if (!g_shared.cfg.in_place_sweeps) {
        memcpy(g_shared.new_values, g_shared.values, (size_t)g_shared.n_states * sizeof(float));
    }
    g_shared.next_state = 0u;
    g_shared.delta = 0.0f;
    g_shared.sweeps = 0u;
    g_shared.greedy_changed = false;
    g_shared.stable_sweeps = 0u;
    g_shared.planning = true;
    g_shared.policy_pass = false;
}

static void set_policy(uint32_t s, uint8_t p)
{
    uint32_t shift_bits = 2u * (s % POLICY_STATES_PER_BYTE);
    uint8_t *byte = &g_shared.policy[s / POLICY_STATES_PER_BYTE];
    *byte = (uint8_t)((*byte & ~(3u << shift_bits)) | ((uint32_t)p << shift_bits));
}

/* planning.plan_rows' policy for state s: argmax of Q from the final values, a tie TIED or drawn (the
   states in order, so the draws are Python's). */
static void derive_policy(uint32_t s, rng_t *rng)
{
    const learner_config_t *c = &g_shared.cfg;
    float d = 0.0f;
    if (s != g_shared.terminal) {
        d = action_value(s, 1u, g_shared.values) - action_value(s, 0u, g_shared.values);
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

/* planning.plan_rows' early stop: whether state s's greedy action (a2 when q1 > q0) differs from its last sweep's
   (the first sweep of a plan counts as a change everywhere, as Python's "no action yet"). */
static void note_greedy(uint32_t s, bool a2)
{
    uint8_t *byte = &g_shared.greedy[s / 8u];
    uint8_t bit = (uint8_t)(1u << (s % 8u));
    if (((*byte & bit) != 0u) != a2) {
        g_shared.greedy_changed = true;
        *byte = (uint8_t)(a2 ? *byte | bit : *byte & ~bit);
    }
}

/* After a whole sweep (sweeps already counted): whether the early stop ends the plan here. */
static bool settled(void)
{
    if (g_shared.greedy == NULL) {
        return false;
    }
    bool changed = g_shared.greedy_changed || g_shared.sweeps == 1u;
    g_shared.greedy_changed = false;
    g_shared.stable_sweeps = changed ? 0u : g_shared.stable_sweeps + 1u;
    return g_shared.stable_sweeps >= g_shared.cfg.plan_stable_sweeps
           && g_shared.delta < g_shared.cfg.plan_loose_tolerance;
}

bool shared_plan_backups(uint32_t max_backups, rng_t *rng)
{
    if (!g_shared.planning) {
        return true;
    }
    for (uint32_t i = 0u; i < max_backups; i++) {
        uint32_t s = g_shared.next_state;
        if (g_shared.policy_pass) {
            /* The policy costs what a backup does (two Q values per state): sliced the same way. */
            derive_policy(s, rng);
            g_shared.next_state++;
            if (g_shared.next_state == g_shared.n_states) {
                g_shared.planning = false;
                return true;
            }
            continue;
        }
        float best = action_value(s, 0u, g_shared.values);
        float q1 = action_value(s, 1u, g_shared.values);
        if (g_shared.greedy != NULL) {
            note_greedy(s, q1 > best);
        }
        best = q1 > best ? q1 : best;
        float change = fabsf(best - g_shared.values[s]);
        g_shared.delta = change > g_shared.delta ? change : g_shared.delta;
        g_shared.new_values[s] = best;  /* the same array with in-place sweeps */
        g_shared.next_state++;
        if (g_shared.next_state < g_shared.terminal) {
            continue;
        }
        /* A sweep is complete. */
        if (!g_shared.cfg.in_place_sweeps) {
            memcpy(g_shared.values, g_shared.new_values, (size_t)g_shared.terminal * sizeof(float));
        }
        g_shared.sweeps++;
        bool converged = g_shared.delta < g_shared.cfg.vi_tol || settled();
        g_shared.next_state = 0u;
        g_shared.delta = 0.0f;
        if (converged || g_shared.sweeps >= g_shared.cfg.max_sweeps) {
            g_shared.policy_pass = true;  /* the policy of the plan in progress is final only when this pass ends */
        }
    }
    return false;
}

uint32_t shared_sweeps(void)
{
    return g_shared.sweeps;
}

float shared_value(uint16_t s)
{
    return s < g_shared.n_states ? g_shared.values[s] : 0.0f;
}

uint8_t shared_policy(uint16_t s)
{
    if (s >= g_shared.n_states) {
        return 0u;
    }
    return (uint8_t)((g_shared.policy[s / POLICY_STATES_PER_BYTE] >> (2u * (s % POLICY_STATES_PER_BYTE))) & 3u);
}

float shared_q(uint16_t s, uint8_t a)
{
    if (s >= g_shared.terminal || a >= LEARNER_ACTIONS) {
        return 0.0f;
    }
    return action_value(s, a, g_shared.values);
}
