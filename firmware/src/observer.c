/* Boundary-layer sliding mode velocity observer (diving-agent.md s. 3), float as on the Teensy. */
#include "observer.h"

#include <math.h>

static float sat_unit(float x)
{
    return x < -1.0f ? -1.0f : (x > 1.0f ? 1.0f : x);
}

void smo_reset(smo_state_t *o, float depth_m)
{
    o->x1_m = depth_m;
    o->x2_mps = 0.0f;
}

float smo_update(smo_state_t *o, const smo_gains_t *g, float measured_depth_m, float dt_s)
{
    o->x1_m -= dt_s * g->rho_mps * sat_unit((o->x1_m - measured_depth_m) / g->phi_m);
    /* The velocity filter sees the updated depth estimate, as simulator/observer.py. */
    o->x2_mps += dt_s / g->tau_s * (-o->x2_mps - g->rho_mps * sat_unit((o->x1_m - measured_depth_m) / g->phi_m));
    return o->x2_mps;
}

void vfilter_start(vfilter_state_t *f, float depth_m, float velocity_mps)
{
    f->z_m = depth_m;
    f->v_mps = velocity_mps;
}

float vfilter_update(vfilter_state_t *f, const vfilter_gains_t *g, float measured_depth_m, float cmd_offset_deg,
                     float dt_s)
{
    float v = f->v_mps;
    float acc = g->accel_per_deg * cmd_offset_deg - g->drag_per_m * v * fabsf(v) + f->bias_mps2;
    float z = f->z_m + dt_s * v + 0.5f * dt_s * dt_s * acc;
    float r;
    v += dt_s * acc;
    r = measured_depth_m - z;
    f->z_m = z + g->depth_gain * r;
    f->v_mps = v + g->velocity_gain * r / dt_s;
    f->bias_mps2 += g->bias_gain * r / (dt_s * dt_s);
    return f->v_mps;
}
