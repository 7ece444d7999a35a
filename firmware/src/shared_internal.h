/* What shared.c (layout, recording, inspection) and shared_plan.c (Q, planning, policy) share: the learner's
   state and the grid arithmetic both need on every slot (inline, so planning's inner loop stays call-free).
   Private to those two files; everything else goes through shared.h. */
#ifndef SHARED_INTERNAL_H
#define SHARED_INTERNAL_H

#include "shared.h"

#define DZ_MAX 2
#define DV_MAX 8
#define DB_MAX 1
#define DV_SPAN (2 * DV_MAX + 1)
#define DB_SPAN (2 * DB_MAX + 1)
#define STATE_INDEX_U8_LIMIT 256u
#define POLICY_STATES_PER_BYTE 4u

typedef struct {
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
    uint8_t *greedy;           /* each state's greedy action in the last sweep, 1 bit (plan_stable_sweeps > 0) */
    uint16_t *since_plan;      /* per type: transitions counted since the last plan, saturating (plan_growth > 0) */
    float z_reward[SHARED_MAX_Z_CELLS];  /* reward of arriving in each depth cell (cell_reward of learning) */
    float v_penalty[SHARED_MAX_ZDOT_CELLS];  /* what arriving in each velocity cell costs (0 without vel_penalty) */
    /* planning in progress */
    uint32_t next_state;       /* where the current sweep resumes */
    float delta;               /* max |change| of the current sweep so far */
    uint32_t sweeps;
    bool planning;
    bool policy_pass;          /* values final: the policy is being derived, state by state */
    bool greedy_changed;       /* a state's greedy action changed in the current sweep */
    uint32_t stable_sweeps;    /* sweeps in a row that changed no greedy action */
} shared_learner_t;

/* The one shared-model learner (defined in shared.c). */
extern shared_learner_t g_shared;

/* The types of a grid: one per (velocity cell, actuator bin, action). */
static inline uint32_t types_of(const learner_config_t *c)
{
    return (uint32_t)c->zdot_cells * c->act_bins * LEARNER_ACTIONS;
}

static inline uint32_t type_of(uint32_t s, uint8_t a)
{
    const learner_config_t *c = &g_shared.cfg;
    uint32_t iv = s % c->zdot_cells;
    uint32_t ib = s / ((uint32_t)c->zdot_cells * c->z_cells);
    return (ib * c->zdot_cells + iv) * LEARNER_ACTIONS + a;
}

/* learning.shared._shift: the successor of s under an offset code, terminal when it leaves the region. */
static inline uint32_t shift(uint32_t s, uint8_t code)
{
    const learner_config_t *c = &g_shared.cfg;
    if (code == SHARED_FAR) {
        return g_shared.terminal;
    }
    int32_t db = (int32_t)(code % DB_SPAN) - DB_MAX;
    int32_t dv = (int32_t)((code / DB_SPAN) % DV_SPAN) - DV_MAX;
    int32_t dz = (int32_t)(code / (DB_SPAN * DV_SPAN)) - DZ_MAX;
    int32_t iv = (int32_t)(s % c->zdot_cells) + dv;
    int32_t iz = (int32_t)((s / c->zdot_cells) % c->z_cells) + dz;
    int32_t ib = (int32_t)(s / ((uint32_t)c->zdot_cells * c->z_cells)) + db;
    ib = ib < 0 ? 0 : ib > (int32_t)c->act_bins - 1 ? (int32_t)c->act_bins - 1 : ib;
    if (iz < 0 || iz >= (int32_t)c->z_cells) {
        return g_shared.terminal;
    }
    if (iv < 0 || iv >= (int32_t)c->zdot_cells) {
        if (!c->depth_only_terminal) {
            return g_shared.terminal;
        }
        iv = iv < 0 ? 0 : (int32_t)c->zdot_cells - 1;
    }
    return ((uint32_t)ib * c->z_cells + (uint32_t)iz) * c->zdot_cells + (uint32_t)iv;
}

static inline float cell_reward(uint32_t s)
{
    if (s == g_shared.terminal) {
        return g_shared.cfg.term_reward;
    }
    return g_shared.z_reward[(s / g_shared.cfg.zdot_cells) % g_shared.cfg.z_cells]
           - g_shared.v_penalty[s % g_shared.cfg.zdot_cells];
}

static inline uint16_t *local_counts(uint32_t pair)
{
    return g_shared.wide ? g_shared.local16[pair].count : g_shared.local8[pair].count;
}

#endif
