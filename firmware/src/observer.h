/* Boundary-layer sliding mode velocity observer (diving-agent.md s. 3; simulator/observer.py). */
#ifndef OBSERVER_H
#define OBSERVER_H

typedef struct {
    float x1_m;    /* depth estimate */
    float x2_mps;  /* velocity estimate */
} smo_state_t;

typedef struct {
    float rho_mps;  /* switching gain */
    float tau_s;    /* velocity filter time constant */
    float phi_m;    /* boundary layer */
} smo_gains_t;

/* Start at depth_m and rest. */
void smo_reset(smo_state_t *o, float depth_m);

/* One step on a depth reading taken dt_s after the previous one; returns the velocity estimate. */
float smo_update(smo_state_t *o, const smo_gains_t *g, float measured_depth_m, float dt_s);

#endif
