/* The count model of paper Alg. 3 over sparse successor slots: recording transitions (evicting the least
   counted slot when a row is full), and reading counts back; with shared_model, shared.c records instead.
   The state it works on is learner.c's (learner_internal.h). */
#include "learner_internal.h"
#include "shared.h"

static void succ_set(uint32_t cell, uint16_t s_next)
{
    if (g_learner.wide_index) {
        g_learner.succ_idx16[cell] = s_next;
    } else {
        g_learner.succ_idx8[cell] = (uint8_t)s_next;
    }
}

static uint32_t row_total(uint32_t row)
{
    const uint16_t *cnt = &g_learner.succ_cnt[row * g_learner.cfg.slots];
    uint32_t total = 0u;
    for (uint32_t k = 0u; k < g_learner.cfg.slots; k++) {
        total += cnt[k];
    }
    return total;
}

uint32_t learner_cell(float depth_m, float velocity_mps, float target_m, float actuator_fraction)
{
    return g_learner.cfg.shared_model ? shared_raw_cell(depth_m, velocity_mps, target_m, actuator_fraction) : 0u;
}

uint32_t learner_evictions(void)
{
    return g_learner.cfg.shared_model && g_learner.n_states != 0u ? shared_evictions() : 0u;
}

void learner_observe_cell(uint16_t s, uint8_t a, float reward, uint16_t s_next, uint32_t next_cell)
{
    if (g_learner.n_states == 0u || s >= learner_terminal() || a >= LEARNER_ACTIONS || s_next >= g_learner.n_states) {
        return;
    }
    if (g_learner.cfg.shared_model) {
        shared_observe(s, a, s_next, next_cell);
        return;
    }
    learner_observe(s, a, reward, s_next);
}

void learner_observe(uint16_t s, uint8_t a, float reward, uint16_t s_next)
{
    if (g_learner.n_states == 0u || s >= learner_terminal() || a >= LEARNER_ACTIONS || s_next >= g_learner.n_states) {
        return;
    }
    if (g_learner.cfg.shared_model) {
        /* the cell of a live successor is its own; a terminal one lies out of reach */
        shared_observe(s, a, s_next, s_next == learner_terminal() ? SHARED_FAR_CELL : shared_state_cell(s_next));
        return;
    }
    uint32_t row = (uint32_t)s * LEARNER_ACTIONS + a;
    uint32_t first = row * g_learner.cfg.slots;
    uint16_t *cnt = &g_learner.succ_cnt[first];
    int32_t slot = -1;
    int32_t free_slot = -1;
    for (uint32_t k = 0u; k < g_learner.cfg.slots; k++) {
        if (cnt[k] > 0u) {
            if (learner_succ_get(first + k) == s_next) {
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
            for (uint32_t k = 1u; k < g_learner.cfg.slots; k++) {
                if (cnt[k] < cnt[free_slot]) {
                    free_slot = (int32_t)k;
                }
            }
            uint32_t total = row_total(row);
            uint32_t kept = total - cnt[free_slot];
            g_learner.reward_sum[row] *= (float)kept / (float)total;
            cnt[free_slot] = 0u;
        }
        slot = free_slot;
        succ_set(first + (uint32_t)slot, s_next);
    }
    if (cnt[slot] == LEARNER_COUNT_MAX) {
        /* Saturation: halve the row (rounding up keeps every seen successor); proportions survive. */
        uint32_t total = row_total(row);
        for (uint32_t k = 0u; k < g_learner.cfg.slots; k++) {
            cnt[k] = (uint16_t)((cnt[k] + 1u) / 2u);
        }
        g_learner.reward_sum[row] *= (float)row_total(row) / (float)total;
    }
    cnt[slot]++;
    g_learner.reward_sum[row] += reward;
}

uint16_t learner_count(uint8_t a, uint16_t s, uint16_t s_next)
{
    if (s >= g_learner.n_states || a >= LEARNER_ACTIONS) {
        return 0u;
    }
    if (g_learner.cfg.shared_model) {
        return s < learner_terminal() && s_next < g_learner.n_states ? shared_count(a, s, s_next) : 0u;
    }
    uint32_t first = ((uint32_t)s * LEARNER_ACTIONS + a) * g_learner.cfg.slots;
    for (uint32_t k = 0u; k < g_learner.cfg.slots; k++) {
        if (g_learner.succ_cnt[first + k] > 0u && learner_succ_get(first + k) == s_next) {
            return g_learner.succ_cnt[first + k];
        }
    }
    return 0u;
}

bool learner_tried(uint16_t s)
{
    if (s >= learner_terminal()) {
        return false;
    }
    if (g_learner.cfg.shared_model) {
        return shared_tried(s);
    }
    return row_total((uint32_t)s * LEARNER_ACTIONS) > 0u || row_total((uint32_t)s * LEARNER_ACTIONS + 1u) > 0u;
}
