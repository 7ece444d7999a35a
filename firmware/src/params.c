/* Parameter values as the agent stores them (f32), checked against the generated table. */
#include "params.h"

#include <string.h>

#include "dumps.h"
#include "text.h"
#include "wire.h"

static float g_values[PARAM_COUNT];

void verdict_ok(verdict_t *v) {
    v->result = ACK_RESULT_ACCEPTED;
    v->reason[0] = '\0';
}

void verdict_set(verdict_t *v, uint8_t result, const char *reason) {
    v->result = result;
    text_copy(v->reason, sizeof v->reason, reason);
}

void params_init(void) {
    for (unsigned i = 0; i < PARAM_COUNT; i++) { g_values[i] = param_defs[i].default_value; }
}

float params_get(param_index_t i) { return g_values[i]; }

bool params_lookup(int16_t index, const char name[PARAM_NAME_BYTES], uint16_t *out, verdict_t *v) {
    if (index == -1) {
        for (uint16_t i = 0; i < PARAM_COUNT; i++) {
            if (memcmp(param_defs[i].name, name, PARAM_NAME_BYTES) == 0) {
                *out = i;
                return true;
            }
        }
        text_buffer_t t;
        text_start(&t, v->reason, sizeof v->reason);
        text_add(&t, "no parameter named '");
        text_add_n(&t, name, PARAM_NAME_BYTES);
        text_add(&t, "'");
        v->result = ACK_RESULT_BAD_VALUE;
        return false;
    }
    if (index < 0 || index >= (int16_t)PARAM_COUNT) {
        text_buffer_t t;
        text_start(&t, v->reason, sizeof v->reason);
        text_add(&t, "no parameter with index ");
        text_add_int(&t, index);
        v->result = ACK_RESULT_BAD_VALUE;
        return false;
    }
    *out = (uint16_t)index;
    return true;
}

void params_learner_config(learner_config_t *c) {
    learner_default_config(c);
    c->z_tol_m = g_values[PARAM_Z_TOL_M];
    c->zdot_tol_mps = g_values[PARAM_ZDOT_TOL_MPS];
    c->z_cells = (uint8_t)g_values[PARAM_Z_CELLS];
    c->zdot_cells = (uint8_t)g_values[PARAM_ZDOT_CELLS];
    c->act_bins = (uint8_t)g_values[PARAM_ACT_BINS];
    c->gamma = g_values[PARAM_GAMMA];
    c->vi_tol = g_values[PARAM_VI_TOL];
    c->term_reward = g_values[PARAM_TERM_REWARD];
    c->p_explore_start = g_values[PARAM_P_EXPLORE_START];
    c->p_explore_end = g_values[PARAM_P_EXPLORE_END];
    c->explore_decay_episodes = (uint32_t)g_values[PARAM_EXPLORE_EPS];
    c->known_count = (uint16_t)g_values[PARAM_KNOWN_COUNT];
    c->depth_only_terminal = g_values[PARAM_DEPTH_ONLY_TERM] != 0.0f;
    c->random_ties = g_values[PARAM_RANDOM_TIES] != 0.0f;
    c->max_sweeps = (uint32_t)g_values[PARAM_MAX_SWEEPS];
    c->in_place_sweeps = g_values[PARAM_IN_PLACE_SWEEPS] != 0.0f;
    c->shared_model = g_values[PARAM_SHARED_MODEL] != 0.0f;
    c->dirichlet_w = g_values[PARAM_DIRICHLET_W];
    c->count_bonus = g_values[PARAM_COUNT_BONUS];
    c->vel_diff_steps = (uint8_t)g_values[PARAM_VEL_DIFF_STEPS];
    c->ties_per_step = g_values[PARAM_TIES_PER_STEP] != 0.0f;
    c->vel_penalty = g_values[PARAM_VEL_PENALTY];
    c->plan_stable_sweeps = (uint16_t)g_values[PARAM_PLAN_STABLE_SWEEPS];
    c->plan_loose_tolerance = g_values[PARAM_PLAN_LOOSE_TOL];
    c->fine_step_deg = g_values[PARAM_FINE_STEP_DEG];
    c->fine_speed_mps = g_values[PARAM_FINE_SPEED_MPS];
    c->fine_reversal_deg = g_values[PARAM_FINE_REVERSAL_DEG];
    c->plan_growth = g_values[PARAM_PLAN_GROWTH];
    if (g_values[PARAM_VELOCITY_FILTER] != 0.0f) {
        /* learning/presets.py VELOCITY_FILTER (tests/firmware/test_ctl_velocity_filter.py compares them). */
        c->filter_depth_gain = 0.271f;
        c->filter_velocity_gain = 0.0285f;
        c->filter_bias_gain = 0.0005f;
        c->filter_accel_per_deg = -0.0022734f;
        c->filter_drag_per_m = 2.0864f;
        c->filter_depth_state = true;
    }
}

static uint32_t n_states(const learner_config_t *c) {
    return (uint32_t)c->z_cells * c->zdot_cells * c->act_bins + 1u;
}

/* SPEC.md s. 13: the learner plus 4 copies of the largest copied snapshot (Q_VALUES; VALUES for a shared model,
   whose Q_VALUES is rendered live). */
uint32_t params_ram_bytes(const learner_config_t *c) {
    uint32_t per_state = c->shared_model ? PARAM_SHARED_SNAPSHOT_BYTES_PER_STATE : PARAM_SNAPSHOT_BYTES_PER_STATE;
    return learner_memory_bytes(c) + PARAM_SNAPSHOTS_HELD * per_state * n_states(c);
}

/* BAD_VALUE reasons: not finite, not integral, outside [min, max], a model too big for the RAM. */
static bool check_value(const param_def_t *d, uint64_t bits, float *stored, verdict_t *v) {
    text_buffer_t t;
    text_start(&t, v->reason, sizeof v->reason);
    text_add_n(&t, d->name, PARAM_NAME_BYTES);
    v->result = ACK_RESULT_BAD_VALUE;
    if (!f64_bits_finite(bits)) {
        text_add(&t, ": not a finite number");
        return false;
    }
    if (d->param_type == PARAM_TYPE_F32) {
        float f = f64_bits_to_f32(bits);
        if (!(f >= d->minimum && f <= d->maximum)) {
            text_add(&t, ": outside [");
            text_add_float(&t, d->minimum);
            text_add(&t, ", ");
            text_add_float(&t, d->maximum);
            text_add(&t, "]");
            return false;
        }
        *stored = f;
        return true;
    }
    int64_t n = 0;
    if (!f64_bits_to_integer(bits, &n)) {
        text_add(&t, ": not an integer");
        return false;
    }
    /* Integer bounds are small (|bound| < 2^24): exact as f32, converted without a 64-bit float conversion. */
    if (n < (int64_t)(int32_t)d->minimum || n > (int64_t)(int32_t)d->maximum) {
        text_add(&t, ": ");
        text_add_int(&t, (int32_t)(n < -2000000000 ? -2000000000 : n > 2000000000 ? 2000000000 : n));
        text_add(&t, " outside [");
        text_add_int(&t, (int32_t)d->minimum);
        text_add(&t, ", ");
        text_add_int(&t, (int32_t)d->maximum);
        text_add(&t, "]");
        return false;
    }
    *stored = (float)n;
    return true;
}

/* A learner parameter: the learner it makes must be valid and fit the RAM budget. */
static bool check_learner(uint16_t index, float stored, verdict_t *v) {
    float old = g_values[index];
    learner_config_t c;
    g_values[index] = stored;
    params_learner_config(&c);
    g_values[index] = old;
    if (c.filter_depth_gain > 0.0f && c.vel_diff_steps > 0u) {
        /* learning/config.py refuses both in the Python agent, with this reason */
        verdict_set(v, ACK_RESULT_BAD_VALUE, "choose the velocity filter or the depth difference, not both");
        return false;
    }
    if (c.plan_stable_sweeps > 0u && !c.shared_model) {
        /* learning/config.py refuses it in the Python agent, with this reason (learner_configure would too) */
        verdict_set(v, ACK_RESULT_BAD_VALUE,
                    "the early planning stop (plan_stable_sweeps) is for the shared model only");
        return false;
    }
    if (c.plan_growth > 0.0f && !c.shared_model) {
        /* the same for planning on growth (learning/config.py's reason) */
        verdict_set(v, ACK_RESULT_BAD_VALUE, "planning on growth (plan_growth) is for the shared model only");
        return false;
    }
    uint32_t need = params_ram_bytes(&c);
    uint32_t states = n_states(&c);
    if (need <= PARAM_RAM_BUDGET_BYTES && states <= dumps_max_states(c.shared_model) &&
        learner_total_bytes(&c) <= learner_arena_bytes()) {
        return true;
    }
    text_buffer_t t;
    text_start(&t, v->reason, sizeof v->reason);
    text_add_n(&t, param_defs[index].name, PARAM_NAME_BYTES);
    text_add(&t, ": a model of ");
    text_add_uint(&t, states);
    text_add(&t, " states needs ");
    text_add_uint(&t, need);
    text_add(&t, " B of RAM, the budget is ");
    text_add_uint(&t, PARAM_RAM_BUDGET_BYTES);
    text_add(&t, " B");
    v->result = ACK_RESULT_BAD_VALUE;
    return false;
}

void params_set(uint16_t index, uint64_t value_bits, uint8_t mode, bool apply, verdict_t *v) {
    const param_def_t *d = &param_defs[index];
    float stored = 0.0f;
    if (!check_value(d, value_bits, &stored, v)) { return; }
    if (d->learner && !check_learner(index, stored, v)) { return; }
    if (d->refused_in_modes & (1u << mode)) {
        text_buffer_t t;
        text_start(&t, v->reason, sizeof v->reason);
        text_add_n(&t, d->name, PARAM_NAME_BYTES);
        text_add(&t, ": not allowed in ");
        text_add(&t, text_mode_name(mode));
        v->result = ACK_RESULT_NOT_ALLOWED_IN_MODE;
        return;
    }
    verdict_ok(v);
    if (apply) { g_values[index] = stored; }
}

size_t params_value_payload(uint16_t index, uint8_t *out) {
    const param_def_t *d = &param_defs[index];
    msg_param_value_t m;
    m.index = index;
    m.count = PARAM_COUNT;
    m.param_type = d->param_type;
    m.value_bits = f64_bits_from_f32(g_values[index]);
    m.minimum_bits = f64_bits_from_f32(d->minimum);
    m.maximum_bits = f64_bits_from_f32(d->maximum);
    memcpy(m.name, d->name, PARAM_NAME_BYTES);
    return msg_param_value_pack(&m, out);
}
