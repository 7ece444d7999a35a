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

/* The learner's velocity filter (learning/config.py filter_*; simulator/plant/episode.py _velocity_filter): predicts
   one period with the commanded gear angle's acceleration, corrects with the measured depth. An 8-step depth
   difference lags the true velocity by ~0.35 s (more behind a lagging port) and the learned policy then swings
   out of its region (issue 29, docs/learners.md). */
typedef struct {
    float z_m;        /* depth estimate */
    float v_mps;      /* velocity estimate */
    float bias_mps2;  /* acceleration the model misses (a neutral point a few degrees off) */
} vfilter_state_t;

typedef struct {
    float depth_gain;     /* z += depth_gain r */
    float velocity_gain;  /* z' += velocity_gain r / dt */
    float bias_gain;      /* bias += bias_gain r / dt^2 */
    float accel_per_deg;  /* model: z'' = accel_per_deg (alpha_cmd - centre) - drag_per_m z'|z'| + bias */
    float drag_per_m;
} vfilter_gains_t;

/* An episode starts at depth_m and velocity_mps; the bias learnt so far is kept (the same gear). */
void vfilter_start(vfilter_state_t *f, float depth_m, float velocity_mps);

/* One control period of dt_s with the command cmd_offset_deg from the window's centre, then the reading
   measured_depth_m; returns the velocity estimate. */
float vfilter_update(vfilter_state_t *f, const vfilter_gains_t *g, float measured_depth_m, float cmd_offset_deg,
                     float dt_s);

#endif
