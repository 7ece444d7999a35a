/* Value iteration over the count model (paper Alg. 4, errata fixed), in slices of sweeps or backups so that
   planning never holds up a control step, then the greedy policy; the shared model's planning is shared_plan.c.
   The state it works on is learner_state.c's (learner_internal.h); it calls nothing of learner.c. */
#include <math.h>
#include <string.h>

#include "learner_internal.h"
#include "shared.h"

float learner_action_value(uint32_t row, const float *values)
{
    const uint16_t *cnt = &g_learner.succ_cnt[row * g_learner.cfg.slots];
    uint32_t first = row * g_learner.cfg.slots;
    uint32_t total = 0u;
    float weighted = 0.0f;
    for (uint32_t k = 0u; k < g_learner.cfg.slots; k++) {
        if (cnt[k] > 0u) {
            total += cnt[k];
            weighted += (float)cnt[k] * values[learner_succ_get(first + k)];
        }
    }
    bool known = g_learner.cfg.alg4_printed ? total > 0u : total >= g_learner.cfg.known_count;
    if (!known) {
        return g_learner.cfg.alg4_printed ? 0.0f : g_learner.cfg.untried_q;
    }
    /* One division per row instead of one per slot: sum_k (c_k / N) v_k = (sum_k c_k v_k) / N. The
       printed form's row sum of P is 1 for a tried row, so it equals the standard backup here. */
    float n = (float)total;
    return g_learner.reward_sum[row] / n + g_learner.cfg.gamma * (weighted / n);
}

void learner_start_planning(void)
{
    if (g_learner.n_states == 0u) {
        return;  /* never configured */
    }
    if (g_learner.cfg.shared_model) {
        shared_start_planning();
        g_learner.planning = true;
        return;
    }
    uint16_t terminal = learner_terminal_index();
    g_learner.values[terminal] = 0.0f;
    if (!g_learner.cfg.in_place_sweeps) {
        memcpy(g_learner.new_values, g_learner.values, (size_t)g_learner.n_states * sizeof(float));
    }
    g_learner.sweeps = 0u;
    g_learner.planning = true;
}

/* One sweep; returns true when max |change| fell below the tolerance. */
static bool sweep(void)
{
    uint16_t terminal = learner_terminal_index();
    float delta = 0.0f;
    for (uint32_t s = 0u; s < terminal; s++) {
        float best = -INFINITY;
        for (uint32_t a = 0u; a < LEARNER_ACTIONS; a++) {
            float q = learner_action_value(s * LEARNER_ACTIONS + a, g_learner.values);
            best = q > best ? q : best;
        }
        float change = fabsf(best - g_learner.values[s]);
        delta = change > delta ? change : delta;
        g_learner.new_values[s] = best;  /* the same array with in-place sweeps */
    }
    if (!g_learner.cfg.in_place_sweeps) {
        memcpy(g_learner.values, g_learner.new_values, (size_t)terminal * sizeof(float));
    }
    g_learner.sweeps++;
    return delta < g_learner.cfg.vi_tol;
}

/* The greedy policy from the converged values; exact ties at random (one draw per tie, states in order,
   as planning.py, so the same stream gives the same policy). */
static void finish_planning(void)
{
    uint16_t terminal = learner_terminal_index();
    for (uint32_t s = 0u; s < g_learner.n_states; s++) {
        float d = 0.0f;
        if (s != terminal) {
            d = learner_action_value(s * LEARNER_ACTIONS + 1u, g_learner.values) - learner_action_value(s * LEARNER_ACTIONS, g_learner.values);
            d = g_learner.cfg.policy_argmin ? -d : d;
        }
        if (d > 0.0f) {
            g_learner.policy[s] = 1u;
        } else if (d < 0.0f) {
            g_learner.policy[s] = 0u;
        } else if (g_learner.cfg.random_ties && g_learner.cfg.ties_per_step) {
            g_learner.policy[s] = (uint8_t)SHARED_TIED;  /* drawn at every step by learner_act */
        } else {
            g_learner.policy[s] = (uint8_t)(g_learner.cfg.random_ties && rng_coin(&g_learner.rng) ? 1u : 0u);
        }
    }
    g_learner.last_sweeps = g_learner.sweeps;
    g_learner.planning = false;
}

static bool shared_done(bool done)
{
    if (done) {
        g_learner.planning = false;
        g_learner.last_sweeps = shared_sweeps();
    }
    return done;
}

bool learner_plan_slice(uint32_t max_sweeps)
{
    if (!g_learner.planning) {
        return true;
    }
    if (g_learner.cfg.shared_model) {
        uint32_t sweep = learner_terminal_index();
        for (uint32_t i = 0u; i < max_sweeps; i++) {
            if (shared_done(shared_plan_backups(sweep, &g_learner.rng))) {
                return true;
            }
        }
        return false;
    }
    for (uint32_t i = 0u; i < max_sweeps; i++) {
        if (sweep() || g_learner.sweeps >= g_learner.cfg.max_sweeps) {
            finish_planning();
            return true;
        }
    }
    return false;
}

bool learner_plan_backups(uint32_t max_backups)
{
    if (!g_learner.planning) {
        return true;
    }
    if (g_learner.cfg.shared_model) {
        return shared_done(shared_plan_backups(max_backups, &g_learner.rng));
    }
    uint32_t sweep = learner_terminal_index() > 0u ? learner_terminal_index() : 1u;
    return learner_plan_slice((max_backups + sweep - 1u) / sweep);
}

bool learner_planning(void)
{
    return g_learner.planning;
}

uint32_t learner_last_sweeps(void)
{
    return g_learner.last_sweeps;
}
