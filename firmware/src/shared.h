/* The shared (relocatable) transition model of learning/shared.py: one histogram of grid offsets per
   state type (velocity cell, actuator bin, action), pooled over every depth cell.

   learner.c dispatches to this module when learner_config_t.shared_model is set; it is not called by
   anything else. The storage is the Teensy layout learning/shared.py documents, as C types below:
   sizeof(SHARED_STATE_T(Z, V, B)) equals learning's shared_memory_bytes (tests/firmware/
   test_shared_learner.py compiles that check for every shared preset with the Teensy's compiler). */
#ifndef SHARED_H
#define SHARED_H

#include <stdbool.h>
#include <stdint.h>

#include "learner.h"
#include "rng.h"

#define SHARED_SLOTS 12u      /* offset slots per type (learning's sparse_slots) */
#define SHARED_FAR 255u       /* offset code of a successor beyond the codable offsets: terminal */
#define SHARED_TIED 2u        /* policy entry of a tied state drawn at every step (ties_per_step) */
#define SHARED_MAX_Z_CELLS 50u      /* the z_cells parameter's maximum (protocol/parameters.py) */
#define SHARED_MAX_ZDOT_CELLS 50u   /* the zdot_cells parameter's maximum */
#define SHARED_FAR_CELL 0xFFFFFFFFu  /* a next_cell no measurement has: recorded as the FAR offset */

/* One type's histogram: counts, their sum, evictions (saturating), offset codes. 40 B, no padding. */
typedef struct {
    uint16_t count[SHARED_SLOTS];
    uint16_t total;
    uint16_t evictions;
    uint8_t  code[SHARED_SLOTS];
} shared_type_t;

/* Per-state counts of the Dirichlet blend (learning/model.py's sparse slots, no reward sums). */
typedef struct {
    uint16_t count[SHARED_SLOTS];
    uint8_t  succ[SHARED_SLOTS];
} shared_local8_t;   /* up to 256 states */
typedef struct {
    uint16_t count[SHARED_SLOTS];
    uint16_t succ[SHARED_SLOTS];
} shared_local16_t;  /* past 256 states */

/* The learner state of one grid as a type (shared model alone, and with the Dirichlet counts). */
#define SHARED_TYPES(Z, V, B) ((V) * (B) * LEARNER_ACTIONS)
#define SHARED_STATES(Z, V, B) ((Z) * (V) * (B) + 1u)
#define SHARED_STATE_T(Z, V, B) struct { \
    shared_type_t types[SHARED_TYPES(Z, V, B)]; float values[SHARED_STATES(Z, V, B)]; }
#define SHARED_DIRICHLET_STATE_T(Z, V, B, LOCAL) struct { \
    shared_type_t types[SHARED_TYPES(Z, V, B)]; float values[SHARED_STATES(Z, V, B)]; \
    LOCAL local[SHARED_STATES(Z, V, B) * LEARNER_ACTIONS]; }

/* learning's shared_memory_bytes: types, values, local counts with a Dirichlet weight. */
uint32_t shared_memory_bytes(const learner_config_t *c);
/* shared_memory_bytes plus what the firmware keeps besides: the Jacobi sweep buffer (none with in-place
   sweeps) and the policy, 2 bits per state (the plan's action or tied), rounded up to whole words; with
   plan_stable_sweeps also each state's last greedy action, 1 bit per state in whole words; with plan_growth also
   each type's count since the last plan, a uint16 per type in whole words. */
uint32_t shared_total_bytes(const learner_config_t *c);
/* Lays the arrays out from base (learner.c's arena, at least shared_total_bytes long). */
void     shared_carve(uint8_t *base, const learner_config_t *c);
void     shared_reset(void);   /* empty model, values 0 (the arena is already zeroed) */

/* Records s --a--> the raw cell next_cell (learning.shared.raw_cell_kernel's packing), and s_next
   in the local counts with a Dirichlet weight. */
void     shared_observe(uint16_t s, uint8_t a, uint16_t s_next, uint32_t next_cell);
/* The raw cell of a live state (what shared_raw_cell gives for a point inside that state's cell). */
uint32_t shared_state_cell(uint32_t s);
/* The raw cell code of a measurement (inside the region or not). */
uint32_t shared_raw_cell(float depth_m, float velocity_mps, float target_m, float actuator_fraction);
uint16_t shared_count(uint8_t a, uint16_t s, uint16_t s_next);
bool     shared_tried(uint16_t s);  /* a type of s has a count (every slot shifts s somewhere) */
uint32_t shared_evictions(void);
/* Inspection of type t (tests, dumps): slot k's count (its offset code in *code), the total, evictions. */
uint16_t shared_slot(uint32_t t, uint32_t k, uint8_t *code);
uint16_t shared_type_total(uint32_t t);
uint16_t shared_type_evictions(uint32_t t);
/* Transitions type t counted since the last plan (kept only with plan_growth > 0; else 0). */
uint16_t shared_type_since_plan(uint32_t t);

/* learning.shared_plan.plan_due: true with plan_growth 0; else whether some type has counted, since the last plan,
   n > 0 transitions with n >= plan_growth * max(total - n, 1) (in double, as Python). */
bool     shared_plan_due(void);
/* A plan from the current values; every type's count since the last plan starts again from 0. */
void     shared_start_planning(void);
/* Up to max_backups units of the planning in progress: state backups of the sweeps (a sweep may stop in
   the middle and resume at the next call: exactly whole sweeps, in-place or Jacobi), then, once the values
   have converged, the policy state by state (one unit each: two Q values, as a backup). True when planning
   is done (then the policy is new, tied states drawn from rng in state order). */
bool     shared_plan_backups(uint32_t max_backups, rng_t *rng);
uint32_t shared_sweeps(void);

float    shared_value(uint16_t s);
uint8_t  shared_policy(uint16_t s);  /* 0, 1, or SHARED_TIED */
float    shared_q(uint16_t s, uint8_t a);

#endif
