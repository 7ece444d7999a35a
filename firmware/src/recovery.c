/* The sliding mode recovery controller on s = e' + lambda e with a learned neutral angle alpha_avg. */
#include "recovery.h"

/* alpha's running mean is taken while the agent is nearly still (simulator/recovery.py). */
#define AVERAGING_BAND_FACTOR 2.0f

static float clampf(float x, float lo, float hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

static float absf(float x)
{
    return x < 0.0f ? -x : x;
}

void recovery_init(recovery_state_t *r, float alpha_avg_deg)
{
    r->avg_deg = alpha_avg_deg;
    r->calm_s = 0.0f;
    r->elapsed_s = 0.0f;
}

void recovery_restart(recovery_state_t *r)
{
    recovery_init(r, r->avg_deg);
}

float recovery_step(recovery_state_t *r, const recovery_params_t *p, float depth_m, float velocity_mps,
                    float setpoint_m, float actuator_deg, float dt_s, bool *settled, bool *gave_up)
{
    float error_m = depth_m - setpoint_m;
    float surface = velocity_mps + p->lambda_per_s * error_m;
    float sat = clampf(surface / p->phi_mps, -1.0f, 1.0f);
    if (absf(velocity_mps) < AVERAGING_BAND_FACTOR * p->settle_velocity_mps) {
        /* Integral action: alpha at a hover is the neutral angle, so its running mean converges there. */
        r->avg_deg += dt_s / p->avg_time_s * (actuator_deg - r->avg_deg);
    }
    bool calm = absf(error_m) < p->settle_depth_m && absf(velocity_mps) < p->settle_velocity_mps;
    r->calm_s = calm ? r->calm_s + dt_s : 0.0f;
    r->elapsed_s += dt_s;
    *settled = r->calm_s >= p->settle_time_s;
    *gave_up = r->elapsed_s >= p->give_up_s && r->calm_s < p->settle_time_s;
    float cmd = r->avg_deg + p->gain_deg * sat;
    if (p->near_gain_deg > 0.0f) {
        /* A steep inner layer: each reversal of s steps the command by up to 2 near_gain_deg, which takes
           up the gear's lost motion that the outer gain alone would limit-cycle on (simulator/recovery.py). */
        cmd += p->near_gain_deg * clampf(surface / p->near_phi_mps, -1.0f, 1.0f);
    }
    return clampf(cmd, 0.0f, p->alpha_max_deg);
}

float recovery_alpha_avg_deg(const recovery_state_t *r)
{
    return r->avg_deg;
}
