/* What learner.c (configuration, the arena, the count model, acting, inspection) and learner_plan.c (value
   iteration, sliced, and the policy) share through learner_state.c: the learner's state and the successor lookup planning's inner loop
   makes on every slot (inline, so that loop stays call-free). Private to those two files; everything else goes
   through learner.h. */
#ifndef LEARNER_INTERNAL_H
#define LEARNER_INTERNAL_H

#include "learner.h"
#include "rng.h"

typedef struct {
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
} learner_state_t;

/* The one learner (defined in learner_state.c, so that learner.c and learner_plan.c both build on it and
   neither on the other's definitions: learner.c calls planning, planning never calls back). */
extern learner_state_t g_learner;

/* The terminal state's index: always the last (learner.h's learner_terminal returns this). */
static inline uint16_t learner_terminal_index(void)
{
    return (uint16_t)(g_learner.n_states - 1u);
}

static inline uint16_t learner_succ_get(uint32_t cell)
{
    return g_learner.wide_index ? g_learner.succ_idx16[cell] : g_learner.succ_idx8[cell];
}

/* Q of one pair from the count model and the given values (planning.py _action_value). */
float learner_action_value(uint32_t row, const float *values);

/* A planning run from the current values; learner_plan_slice / learner_plan_backups carry it out. */
void learner_start_planning(void);

#endif
