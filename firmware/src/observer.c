/* Boundary-layer sliding mode velocity observer (diving-agent.md s. 3), float as on the Teensy. */
#include "observer.h"

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
