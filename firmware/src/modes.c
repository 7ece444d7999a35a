/* The mode machine, as simulator/onboard.py (the Python reference) with the SPEC.md 1.1 command matrix.

| mode       | period     | each step                                    | leaves to (when)                          |
|------------|------------|----------------------------------------------|-------------------------------------------|
| IDLE       | control    | actuator at neutral; SAMPLE at 1 Hz          | RECOVERING (CMD_START); HOVER (CMD_HOVER)  |
| RECOVERING | recovery   | recovery controller to a random start depth; | LEARNING (settled and planning done:       |
|            |            | a slice of the learner's planning            |   EPISODE_START);                          |
|            |            |                                              | SURFACING (not settled after give_up_s)    |
| LEARNING   | control    | the learner acts, observes, is rewarded      | RECOVERING (failure or success);           |
|            |            |                                              | SURFACING (episode limit); PAUSED          |
| HOVER      | recovery   | recovery controller holds the hover depth    | RECOVERING (CMD_START); SURFACING (STOP)   |
| PAUSED     | recovery   | recovery controller holds the paused depth   | RECOVERING (CMD_START); SURFACING (STOP)   |
| SURFACING  | control    | actuator at maximum volume                   | IDLE (shallower than CFG_SURFACE_DEPTH_M)  |

In every mode but IDLE and SURFACING: battery below low_batt_v, max_dive_s away from IDLE, or link loss with
surface_on_link_loss -> SURFACING (an episode in progress ends ABORTED). */
#include "modes.h"

#include <string.h>

#include "config.h"
#include "dumps.h"
#include "hal.h"
#include "learner.h"
#include "link.h"
#include "observer.h"
#include "recovery.h"
#include "rng.h"
#include "text.h"
#include "wire.h"

#define TEXT_BYTES 96u

static const smo_gains_t OBSERVER_GAINS = {CFG_OBSERVER_RHO_MPS, CFG_OBSERVER_TAU_S, CFG_OBSERVER_PHI_M};
static const recovery_params_t RECOVERY = {
    CFG_RECOVERY_LAMBDA_PER_S, CFG_RECOVERY_PHI_MPS, CFG_RECOVERY_GAIN_DEG, CFG_RECOVERY_AVG_TIME_S,
    CFG_SETTLE_DEPTH_M, CFG_SETTLE_VELOCITY_MPS, CFG_SETTLE_TIME_S, CFG_GIVE_UP_S, CFG_ALPHA_MAX_DEG,
    CFG_RECOVERY_NEAR_GAIN_DEG, CFG_RECOVERY_NEAR_PHI_MPS,
};

typedef struct {
    uint8_t mode;
    uint32_t next_sample;
    uint32_t episode;        /* current or last episode number */
    uint32_t steps;
    float episode_return;
    int32_t prev_state;      /* -1: no transition to observe yet */
    uint8_t prev_action;
    float center_deg;        /* the learner's window is centred here */
    float cmd_deg;           /* commanded gear angle (clamped to the gear range) */
    float hold_depth_m;      /* recovery / hover / pause set point */
    float surface_pa;        /* P0, measured at boot */
    float pressure_pa, depth_m, velocity_mps;
    uint64_t last_measure_us;
    uint64_t dive_start_us;
    uint64_t next_idle_sample_us;
    uint32_t successes;
    uint32_t generation;     /* SPEC 1.3 s. 6: the learner's generation since boot, +1 at every restart */
    uint32_t episodes_left;  /* 0 = no limit */
    bool dumps_after_planning;
    float last_dt_s;         /* agent time between the last two measurements */
    float depth_ring[CFG_VEL_DIFF_MAX_STEPS];  /* the last k measured depths (vel_diff_steps = k) */
    uint8_t ring_pos;
    uint32_t plan_waits;     /* recovery steps settled but waiting for planning to finish */
    uint32_t forced_plans;   /* episode starts that had to finish planning in one step (a late step) */
    smo_state_t observer;
    vfilter_state_t vfilter;  /* the learner's velocity filter (learner_config_t filter_*) */
    recovery_state_t recovery;
    rng_t rng;
} modes_t;

static modes_t g;
static modes_episode_dumps_t g_episode_dumps;  /* the command handlers' (agent.c) */

static bool held(uint8_t mode) { return mode == MODE_RECOVERING || mode == MODE_HOVER || mode == MODE_PAUSED; }
static bool diving(uint8_t mode) { return held(mode) || mode == MODE_LEARNING; }

static float clampf(float v, float lo, float hi) { return v < lo ? lo : v > hi ? hi : v; }

static void set_cmd(float deg) {
    g.cmd_deg = clampf(deg, 0.0f, CFG_ALPHA_MAX_DEG);
    hal_stepper_set_cmd_deg(g.cmd_deg);
}

static void measure(void) {
    uint64_t now = hal_time_us();
    float dt_s = (float)(uint32_t)(now - g.last_measure_us) * 1e-6f;
    g.last_dt_s = dt_s;
    g.last_measure_us = now;
    g.pressure_pa = hal_pressure_pa();
    g.depth_m = (g.pressure_pa - g.surface_pa) / (CFG_WATER_DENSITY_KGPM3 * CFG_GRAVITY_MPS2);
    g.velocity_mps = smo_update(&g.observer, &OBSERVER_GAINS, g.depth_m, dt_s);
}

static float actuator_fraction(void) { return (g.cmd_deg - g.center_deg) / params_get(PARAM_ACTION_WIN_DEG); }

static bool vfilter_on(void) { return learner_config()->filter_depth_gain > 0.0f; }

/* The depth the learner sees: the filter's estimate (learner_config_t filter_depth_state, so that sensor noise does
   not flicker it between cells) or the reading. SAMPLE still reports the reading. */
static float learner_depth(void) {
    return vfilter_on() && learner_config()->filter_depth_state ? g.vfilter.z_m : g.depth_m;
}

static uint16_t state_now(void) {
    return learner_state(learner_depth(), g.velocity_mps, params_get(PARAM_TARGET_DEPTH_M), actuator_fraction());
}

static uint32_t vel_diff_steps(void) { return (uint32_t)params_get(PARAM_VEL_DIFF_STEPS); }

/* simulator/observer.py DepthDifference: a flat history at the current depth (it was measured all along). */
static void depth_ring_reset(void) {
    for (uint32_t i = 0; i < CFG_VEL_DIFF_MAX_STEPS; i++) { g.depth_ring[i] = g.depth_m; }
    g.ring_pos = 0;
}

/* The learner's velocity from its filter, which predicts with the command of the last period. */
static float filtered_velocity(void) {
    const learner_config_t *c = learner_config();
    vfilter_gains_t gains = {c->filter_depth_gain, c->filter_velocity_gain, c->filter_bias_gain,
                             c->filter_accel_per_deg, c->filter_drag_per_m};
    return vfilter_update(&g.vfilter, &gains, g.depth_m, g.cmd_deg - g.center_deg, g.last_dt_s);
}

/* The learner's velocity (z_t - z_{t-k}) / (k dt) over its own measured depths. */
static float depth_difference(uint32_t k) {
    float oldest = g.depth_ring[g.ring_pos];
    g.depth_ring[g.ring_pos] = g.depth_m;
    g.ring_pos = (uint8_t)((g.ring_pos + 1u) % k);
    return (g.depth_m - oldest) / ((float)k * g.last_dt_s);
}

static void sample(uint8_t action, float reward, uint16_t state) {
    uint8_t payload[MSG_SAMPLE_FIXED_BYTES];
    msg_sample_t m = {
        hal_time_us(), g.next_sample, g.episode, g.steps, g.pressure_pa, g.depth_m, g.velocity_mps,
        hal_stepper_deg(), g.cmd_deg, reward, state, action, g.mode,
    };
    uint32_t index = g.next_sample++;
    link_send_logged(MSG_SAMPLE_ID, payload, msg_sample_pack(&m, payload), index, true);
}

static void say(const char *a, const char *b, const char *c) {
    char line[TEXT_BYTES];
    text_buffer_t t;
    text_start(&t, line, sizeof line);
    text_add(&t, a);
    text_add(&t, b);
    text_add(&t, c);
    link_text(SEVERITY_INFO, line);
}

static float uniform_pm1(void) {
    return (float)(uint32_t)(rng_next_u64(&g.rng) >> 40) * (2.0f / 16777216.0f) - 1.0f;
}

static void enter(uint8_t mode, const char *why) {
    if (mode == g.mode) { return; }
    if (g.mode == MODE_IDLE) { g.dive_start_us = hal_time_us(); }
    char line[TEXT_BYTES];
    text_buffer_t t;
    text_start(&t, line, sizeof line);
    text_add(&t, "mode ");
    text_add(&t, text_mode_name(g.mode));
    text_add(&t, " -> ");
    text_add(&t, text_mode_name(mode));
    text_add(&t, ": ");
    text_add(&t, why);
    link_text(SEVERITY_INFO, line);
    g.mode = mode;
    if (held(mode)) { recovery_restart(&g.recovery); }
    if (mode == MODE_RECOVERING) {
        float half_m = CFG_START_DEPTH_FRACTION * params_get(PARAM_Z_TOL_M);
        g.hold_depth_m = params_get(PARAM_TARGET_DEPTH_M) + half_m * uniform_pm1();
    }
}

static void reset_episode(void) {
    g.episode = learner_episode();
    g.steps = 0;
    g.episode_return = 0.0f;
    g.prev_state = -1;
    g.prev_action = 0;
    g.center_deg = CFG_NEUTRAL_DEG;
}

static void end_episode(uint8_t reason, uint16_t state) {
    learner_end_episode();  /* planning runs in slices during the next recovery */
    dumps_model_changed();
    if (reason == END_REASON_SUCCESS) { g.successes++; }
    uint8_t payload[MSG_EPISODE_END_FIXED_BYTES];
    msg_episode_end_t m = {
        hal_time_us(), g.episode, g.next_sample - 1u, reason, state, g.steps,
        (float)g.steps * params_get(PARAM_CONTROL_DT_S), g.episode_return, g.successes, g.generation,
    };
    link_send_logged(MSG_EPISODE_END_ID, payload, msg_episode_end_pack(&m, payload), g.next_sample - 1u, false);
    if (params_get(PARAM_DUMP_EACH_EPISODE) != 0.0f) { g.dumps_after_planning = true; }
    if (reason == END_REASON_ABORTED) { return; }
    if (g.episodes_left != 0u) {
        g.episodes_left--;
        if (g.episodes_left == 0u) {
            enter(MODE_SURFACING, "episode limit reached");
            return;
        }
    }
    enter(MODE_RECOVERING, reason == END_REASON_SUCCESS ? "episode success" : "episode failure");
}

static void abort_episode(void) {
    if (g.mode == MODE_LEARNING) { end_episode(END_REASON_ABORTED, state_now()); }
}

static void surface(const char *why) {
    abort_episode();
    enter(MODE_SURFACING, why);
}

/* Planning of the last episode, a few sweeps per call; the episode dumps wait for the new values. */
static void plan(bool to_completion) {
    if (learner_planning()) {
        if (to_completion) {
            (void)learner_plan_slice(0xFFFFFFFFu);
        } else if (learner_config()->shared_model) {
            (void)learner_plan_backups(CFG_PLAN_BACKUPS_PER_STEP);
        } else {
            (void)learner_plan_slice(CFG_PLAN_SWEEPS_PER_STEP);
        }
        /* A shared model's Q_VALUES snapshot is rendered from the values, which planning changes. */
        if (learner_config()->shared_model) { dumps_model_changed(); }
    }
    if (!learner_planning() && g.dumps_after_planning) {
        g.dumps_after_planning = false;
        g_episode_dumps();
    }
}

static void begin_episode(float center_deg) {
    if (learner_planning()) {
        g.forced_plans++;  /* not reached: RECOVERING waits for planning (controller_step) */
        plan(true);  /* the next episode acts on the finished plan */
    }
    reset_episode();
    depth_ring_reset();
    if (vel_diff_steps() > 0u) { g.velocity_mps = 0.0f; }  /* as simulator/onboard.py: a flat history */
    if (vfilter_on()) {
        vfilter_start(&g.vfilter, g.depth_m, 0.0f);  /* handed over at rest, as simulator/plant/episode.py */
        g.velocity_mps = 0.0f;
    }
    g.episode = learner_episode() + 1u;
    g.center_deg = center_deg;
    set_cmd(center_deg);
    uint16_t start_state = state_now();
    say("mode ", text_mode_name(g.mode), " -> LEARNING: new episode");
    g.mode = MODE_LEARNING;
    uint8_t payload[MSG_EPISODE_START_FIXED_BYTES];
    msg_episode_start_t m = {
        hal_time_us(), g.episode, g.next_sample, start_state, g.depth_m, g.velocity_mps,
        params_get(PARAM_TARGET_DEPTH_M), params_get(PARAM_Z_TOL_M), params_get(PARAM_ZDOT_TOL_MPS),
        learner_p_explore(), g.generation,
    };
    link_send_logged(MSG_EPISODE_START_ID, payload, msg_episode_start_pack(&m, payload), g.next_sample, false);
}

static void learning_step(void) {
    measure();
    uint32_t k = vel_diff_steps();
    if (k > 0u) {
        g.velocity_mps = depth_difference(k);
    } else if (vfilter_on()) {
        g.velocity_mps = filtered_velocity();
    }
    uint16_t state = state_now();
    float reward = 0.0f;
    if (g.prev_state >= 0) {
        float target_m = params_get(PARAM_TARGET_DEPTH_M);
        reward = learner_reward(learner_depth(), target_m, state);
        g.episode_return += reward;
        uint32_t cell = learner_cell(learner_depth(), g.velocity_mps, target_m, actuator_fraction());
        learner_observe_cell((uint16_t)g.prev_state, g.prev_action, reward, state, cell);
        dumps_model_changed();
    }
    float limit = params_get(PARAM_SUCCESS_TIME_S) / params_get(PARAM_CONTROL_DT_S);
    if (state == learner_terminal() || (float)g.steps >= limit - 0.5f) {
        sample(ACTION_NONE, reward, state);
        end_episode(state == learner_terminal() ? END_REASON_FAILURE : END_REASON_SUCCESS, state);
        return;
    }
    uint8_t action = learner_act(state);
    bool reversal = g.prev_state < 0 || action != g.prev_action;  /* the episode's first action counts as one */
    float step = learner_step_deg(g.velocity_mps, params_get(PARAM_ACTION_STEP_DEG), reversal);
    float window = params_get(PARAM_ACTION_WIN_DEG);
    float cmd = g.cmd_deg + (action == ACTION_INCREASE_VOLUME ? step : -step);
    set_cmd(clampf(cmd, g.center_deg - window, g.center_deg + window));
    g.prev_state = state;
    g.prev_action = action;
    sample(action, reward, state);
    g.steps++;
}

static void controller_step(float dt_s) {
    measure();
    bool settled = false;
    bool gave_up = false;
    float cmd = recovery_step(&g.recovery, &RECOVERY, g.depth_m, g.velocity_mps, g.hold_depth_m, hal_stepper_deg(),
                              dt_s, &settled, &gave_up);
    set_cmd(cmd);
    sample(ACTION_NONE, 0.0f, 0);
    if (g.mode == MODE_RECOVERING) {
        plan(false);
        if (settled && learner_planning()) {
            g.plan_waits++;  /* hold the start depth a step longer: planning never runs late */
        } else if (settled) {
            begin_episode(recovery_alpha_avg_deg(&g.recovery));
        } else if (gave_up && !learner_planning()) {  /* unsettled while waiting for a long plan: hold on */
            enter(MODE_SURFACING, "recovery did not settle");
        }
    }
}

static void check_limits(void) {
    float battery_v = hal_battery_v();
    float max_dive_s = params_get(PARAM_MAX_DIVE_S);
    float timeout_s = params_get(PARAM_LINK_TIMEOUT_S);
    uint64_t dived_us = hal_time_us() - g.dive_start_us;
    uint64_t silent_us = hal_link_time_us() - link_last_ground_rx_us();
    if (battery_v < params_get(PARAM_LOW_BATT_V)) {
        surface("battery low");
    } else if (max_dive_s > 0.0f && (float)(dived_us / 1000u) >= max_dive_s * 1000.0f) {
        surface("maximum dive time");
    } else if (params_get(PARAM_SURFACE_ON_LINK_LOSS) != 0.0f && timeout_s > 0.0f &&
               (float)(silent_us / 1000u) >= timeout_s * 1000.0f) {
        surface("link lost");
    }
}

void modes_init(modes_episode_dumps_t episode_dumps) {
    memset(&g, 0, sizeof g);
    g_episode_dumps = episode_dumps;
    rng_seed(&g.rng, ((uint64_t)hal_entropy() << 32) | hal_entropy());
    learner_config_t c;
    params_learner_config(&c);
    /* Seeded first: configuring resets the learner, whose first policy breaks ties from this stream. */
    learner_seed(((uint64_t)hal_entropy() << 32) | hal_entropy());
    (void)learner_configure(&c);
    recovery_init(&g.recovery, CFG_NEUTRAL_DEG);
    g.mode = MODE_IDLE;
    g.generation = 1u;
    g.surface_pa = hal_pressure_pa();  /* P0: the agent boots at the surface */
    g.last_measure_us = hal_time_us();
    smo_reset(&g.observer, 0.0f);
    g.pressure_pa = g.surface_pa;
    set_cmd(CFG_NEUTRAL_DEG);
    reset_episode();
}

uint32_t modes_step(void) {
    uint32_t period_us = (uint32_t)(params_get(PARAM_CONTROL_DT_S) * 1e6f + 0.5f);
    if (g.mode == MODE_LEARNING) {
        learning_step();
    } else if (held(g.mode)) {
        period_us = CFG_RECOVERY_PERIOD_US;
        controller_step((float)period_us * 1e-6f);
    } else if (g.mode == MODE_SURFACING) {
        measure();
        set_cmd(CFG_ALPHA_MAX_DEG);
        sample(ACTION_NONE, 0.0f, 0);
        if (g.depth_m < CFG_SURFACE_DEPTH_M) { enter(MODE_IDLE, "at the surface"); }
    } else {
        measure();
        set_cmd(CFG_NEUTRAL_DEG);
        if (hal_time_us() >= g.next_idle_sample_us) {
            g.next_idle_sample_us = hal_time_us() + CFG_IDLE_SAMPLE_US;
            sample(ACTION_NONE, 0.0f, 0);
        }
    }
    if (g.mode != MODE_RECOVERING) { plan(false); }  /* RECOVERING planned above */
    if (diving(g.mode)) { check_limits(); }
    return period_us;
}

uint8_t modes_mode(void) { return g.mode; }
uint32_t modes_episode(void) { return g.episode; }
uint32_t modes_generation(void) { return g.generation; }
uint32_t modes_next_sample(void) { return g.next_sample; }
uint32_t modes_plan_waits(void) { return g.plan_waits; }
uint32_t modes_forced_plans(void) { return g.forced_plans; }

static void not_allowed(verdict_t *v) {
    char line[PARAMS_REASON_BYTES];
    text_buffer_t t;
    text_start(&t, line, sizeof line);
    text_add(&t, "not allowed in ");
    text_add(&t, text_mode_name(g.mode));
    verdict_set(v, ACK_RESULT_NOT_ALLOWED_IN_MODE, line);
}

void modes_cmd_start(uint32_t max_episodes, bool apply, verdict_t *v) {
    if (g.mode != MODE_IDLE && g.mode != MODE_HOVER && g.mode != MODE_PAUSED) { not_allowed(v); return; }
    verdict_ok(v);
    if (!apply) { return; }
    g.episodes_left = max_episodes != 0u ? max_episodes : (uint32_t)params_get(PARAM_MAX_EPISODES);
    enter(MODE_RECOVERING, "CMD_START");
}

void modes_cmd_stop(bool apply, verdict_t *v) {
    verdict_ok(v);  /* IDLE and SURFACING: accepted, the mode stays */
    if (apply && g.mode != MODE_IDLE && g.mode != MODE_SURFACING) { surface("CMD_STOP"); }
}

void modes_cmd_pause(bool apply, verdict_t *v) {
    if (g.mode != MODE_LEARNING && g.mode != MODE_RECOVERING) { not_allowed(v); return; }
    verdict_ok(v);
    if (!apply) { return; }
    abort_episode();
    g.hold_depth_m = g.depth_m;
    enter(MODE_PAUSED, "CMD_PAUSE");
}

void modes_cmd_surface(bool apply, verdict_t *v) {
    verdict_ok(v);
    if (apply && g.mode != MODE_SURFACING) { surface("CMD_SURFACE"); }
}

void modes_cmd_hover(float depth_m, bool apply, verdict_t *v) {
    if (!(depth_m >= 0.0f && depth_m <= CFG_HOVER_MAX_DEPTH_M)) {
        verdict_set(v, ACK_RESULT_BAD_VALUE, "hover depth outside [0, 2.5] m");
        return;
    }
    if (g.mode != MODE_IDLE && g.mode != MODE_HOVER && g.mode != MODE_PAUSED) { not_allowed(v); return; }
    verdict_ok(v);
    if (!apply) { return; }
    g.hold_depth_m = depth_m;
    enter(MODE_HOVER, "CMD_HOVER");
}

static void restart_learner(const char *why) {
    learner_config_t c;
    params_learner_config(&c);
    (void)learner_configure(&c);  /* checked against the arena before the value was accepted */
    memset(&g.vfilter, 0, sizeof g.vfilter);  /* a new learner learns its bias afresh */
    g.successes = 0;
    g.dumps_after_planning = false;
    dumps_model_changed();
    reset_episode();
    g.generation++;  /* a new chapter: its episodes are numbered from 1 again */
    char line[TEXT_BYTES];
    text_buffer_t t;
    text_start(&t, line, sizeof line);
    text_add(&t, why);
    text_add(&t, ", generation ");
    text_add_uint(&t, g.generation);
    link_text(SEVERITY_INFO, line);
}

void modes_cmd_reset_model(bool apply, verdict_t *v) {
    if (g.mode == MODE_LEARNING) { not_allowed(v); return; }
    verdict_ok(v);
    if (!apply) { return; }
    learner_reset();
    restart_learner("model reset: learner restarted");
}

void modes_param_set(uint16_t index, uint64_t value_bits, bool apply, verdict_t *v) {
    /* 1.2 s. 13: setting the current value is no change: it does not restart the learner. */
    float before = index < PARAM_COUNT ? params_get((param_index_t)index) : 0.0f;
    params_set(index, value_bits, g.mode, apply, v);
    if (apply && v->result == ACK_RESULT_ACCEPTED && param_defs[index].learner &&
        params_get((param_index_t)index) != before) {
        restart_learner("learner parameter changed: learner restarted");
    }
}
