/* The on-board learner: paper Section III with its sparse Teensy count model (learning/), in static storage.

   One learner at a time, chosen by learner_config_t. act_bins == 1 is the paper's learner (S = 101 with
   the defaults), act_bins > 1 the actuator-state learner (`actuator3`: the gear position relative to
   neutral joins the state). Value iteration after an episode is sliced: learner_end_episode() starts it
   and learner_plan_slice() runs a bounded number of sweeps per call, so no control step is late. */
#ifndef LEARNER_H
#define LEARNER_H

#include <stdbool.h>
#include <stdint.h>

#define LEARNER_ACTIONS 2u      /* a1 decrease volume, a2 increase volume */
#define LEARNER_COUNT_MAX 65535u  /* uint16 counts, halved on saturation */

/* Bytes of static storage the learner may use (model + values + sweep buffer + policy). A build may
   set it (-DLEARNER_ARENA_BYTES=...) to what its RAM allows; a configuration that does not fit is
   refused (learner_configure returns false). */
#ifndef LEARNER_ARENA_BYTES
#define LEARNER_ARENA_BYTES 40960u
#endif

typedef struct {
    uint8_t  z_cells;                  /* depth cells of the grid */
    uint8_t  zdot_cells;               /* velocity cells */
    uint8_t  act_bins;                 /* actuator bins (1 = paper) */
    uint8_t  slots;                    /* successor slots per (s, a) (sparse_slots) */
    float    z_tol_m;                  /* half-height of the learning region */
    float    zdot_tol_mps;             /* velocity bound of the learning region */
    float    gamma;                    /* discount factor */
    float    vi_tol;                   /* value iteration stops below this max change */
    float    term_reward;              /* reward on entering the terminal state */
    float    p_explore_start;          /* exploration probability at episode 0 */
    float    p_explore_end;            /* .. from explore_decay_episodes on */
    uint32_t explore_decay_episodes;   /* length of the linear decay */
    float    untried_q;                /* Q of a pair tried fewer than known_count times */
    uint16_t known_count;              /* 1 = paper, > 1 R-MAX */
    bool     random_ties;              /* false: ties pick a1, as np.argmax */
    bool     depth_only_terminal;      /* authors' code: leaving in velocity does not end it */
    bool     in_place_sweeps;          /* Gauss-Seidel sweeps instead of Jacobi */
    /* Errata switches (true = the printed pseudo-code, diving-agent.md s. 5). */
    bool     explore_literal_gt;
    bool     policy_argmin;
    bool     alg4_printed;
    uint32_t max_sweeps;               /* safety stop of one planning run */
    /* The shared-model learners (learning/shared.py, shared.c). */
    bool     shared_model;             /* one offset histogram per (velocity cell, actuator bin, action) */
    bool     ties_per_step;            /* shared model: a tied state's action drawn at every step */
    float    dirichlet_w;              /* shared model: per-state counts too, this prior weight (0 = off) */
    float    count_bonus;              /* shared model: beta / sqrt(n) added to a pair's reward (0 = off) */
    uint8_t  vel_diff_steps;           /* the agent's velocity input: k-step depth difference (0 = observer) */
    float    vel_penalty;              /* shared model: a cell's reward also loses this x |its velocity centre| (s) */
    /* The velocity filter (observer.h vfilter_*; 0 depth gain = off, vel_diff_steps or the observer instead). */
    float    filter_depth_gain;
    float    filter_velocity_gain;
    float    filter_bias_gain;
    float    filter_accel_per_deg;     /* m/s^2 per deg of command above the window's centre */
    float    filter_drag_per_m;        /* 1/m */
    bool     filter_depth_state;       /* with the filter: the learner's depth (state, reward, cell) is its estimate */
    /* Shared model: planning also stops once no greedy action has changed for this many sweeps in a row and
       the sweep's max change is below plan_loose_tolerance (0 = off; learning/planning.py plan_rows). */
    uint16_t plan_stable_sweeps;
    float    plan_loose_tolerance;
    /* Shared model: an episode's end plans only once some type has counted, since the last plan, this many times
       the transitions it had then (0 = off, a plan after every episode; learning/shared_plan.py plan_due). */
    float    plan_growth;
    /* A smaller gear step near a hover (learning/config.py fine_step_deg; 0 = off, the plant's step always): an
       action steps fine_step_deg while the learner's |velocity| is under fine_speed_mps (learner_step_deg). */
    float    fine_step_deg;
    float    fine_speed_mps;
    /* There, an action reversing the last one (or the episode's first) steps fine_reversal_deg instead, to take up
       a gear's lost motion (learning/config.py fine_reversal_deg; 0 = off, fine_step_deg always). */
    float    fine_reversal_deg;
} learner_config_t;

/* The defaults of learning/config.py LearnerConfig (the paper's simulation values). */
void learner_default_config(learner_config_t *c);

/* Bytes of the learner as the Teensy holds it: the count model (successor indices, uint8 up to 256
   states, else uint16; uint16 counts; float reward sums), float values and uint8 policy. Equals
   learning's learner_memory_bytes. */
uint32_t learner_memory_bytes(const learner_config_t *c);
/* learner_memory_bytes plus the Jacobi sweep buffer (float per state, none with in-place sweeps):
   everything the learner keeps for c; it must fit the arena. */
uint32_t learner_total_bytes(const learner_config_t *c);
/* Bytes the configured learner's arrays occupy in the arena (== learner_total_bytes of its config). */
uint32_t learner_used_bytes(void);
uint32_t learner_arena_bytes(void);

/* Takes c (copied) and resets; false, with nothing changed, if invalid or larger than the arena. */
bool     learner_configure(const learner_config_t *c);
const learner_config_t *learner_config(void);
/* Seed of the tie-break and exploration stream (a board seeds it from hal_entropy). */
void     learner_seed(uint64_t seed);
/* Forget model, values, policy and episode count (values 0, random tie-broken policy, episode 0). */
void     learner_reset(void);

uint16_t learner_n_states(void);
uint16_t learner_terminal(void);   /* n_states - 1 */
/* State of (depth, velocity, actuator fraction in -1..1 of its window); the terminal state outside. */
uint16_t learner_state(float depth_m, float velocity_mps, float target_m, float actuator_fraction);
float    learner_reward(float depth_m, float target_m, uint16_t s_next);
/* The gear step of an action at the learner's velocity: fine_step_deg near a hover (fine_reversal_deg there if
   set and the action reverses the last one), else plant_step_deg (the action_step_deg parameter);
   learning/acting.py step_size_kernel is its Python twin. */
float    learner_step_deg(float velocity_mps, float plant_step_deg, bool reversal);
/* The policy's action, flipped with the exploration probability of the current episode. */
uint8_t  learner_act(uint16_t s);
void     learner_observe(uint16_t s, uint8_t a, float reward, uint16_t s_next);
/* The raw (unclipped) grid cell of a measurement, which the shared model records for a successor
   (inside the region or not); 0 for the per-state learners, which do not need it. */
uint32_t learner_cell(float depth_m, float velocity_mps, float target_m, float actuator_fraction);
/* learner_observe with the successor's raw cell (learner_cell); learner_observe uses the cell of s_next,
   and for a terminal successor an offset beyond the codable ones (also terminal). */
void     learner_observe_cell(uint16_t s, uint8_t a, float reward, uint16_t s_next, uint32_t next_cell);
uint32_t learner_evictions(void);    /* shared model: slots evicted so far (saturating per type) */

/* Episode over: the episode count advances, planning starts (learner_plan_slice finishes it); with plan_growth > 0
   only if the shared model has grown enough (shared_plan_due): else no planning, last_sweeps 0, the policy stays. */
void     learner_end_episode(void);
/* Up to max_sweeps value iteration sweeps; true when planning is done (then the policy is new). */
bool     learner_plan_slice(uint32_t max_sweeps);
/* Up to max_backups state backups (a sweep is S - 1 of them): a bounded slice whatever S is. The
   shared model resumes a sweep where the last slice stopped; the per-state learners round up to whole
   sweeps. True when planning is done. */
bool     learner_plan_backups(uint32_t max_backups);
bool     learner_planning(void);
uint32_t learner_last_sweeps(void);  /* sweeps of the last completed planning run */

uint32_t learner_episode(void);      /* completed episodes */
float    learner_p_explore(void);
float    learner_value(uint16_t s);
uint8_t  learner_policy(uint16_t s);
/* Q(s, a) from the model and the current values (computed, not stored: 0 for the terminal state). */
float    learner_q(uint16_t s, uint8_t a);
uint16_t learner_count(uint8_t a, uint16_t s, uint16_t s_next);
/* True if s was ever left (a transition counted from it, either action): what POLICY's 255 "untried" tells. */
bool     learner_tried(uint16_t s);

#endif
