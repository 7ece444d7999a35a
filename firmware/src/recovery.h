/* The sliding mode recovery controller between episodes (diving-agent.md s. 4; simulator/recovery.py). */
#ifndef RECOVERY_H
#define RECOVERY_H

#include <stdbool.h>

typedef struct {
    float lambda_per_s;         /* sliding surface s = e' + lambda e */
    float phi_mps;              /* boundary layer of s */
    float gain_deg;             /* gear angle at the edge of the boundary layer */
    float avg_time_s;           /* time constant of the running mean alpha_avg */
    float settle_depth_m;       /* hand over when |e| < settle_depth_m .. */
    float settle_velocity_mps;  /* .. and |z'| < settle_velocity_mps .. */
    float settle_time_s;        /* .. for settle_time_s */
    float give_up_s;            /* not settled within give_up_s: give up */
    float alpha_max_deg;        /* gear range 0 .. alpha_max_deg */
    float near_gain_deg;        /* inner layer: extra angle at its edge, takes up backlash (0 = off) */
    float near_phi_mps;         /* inner boundary layer of s */
} recovery_params_t;

typedef struct recovery_state {
    float avg_deg;    /* learned neutral angle alpha_avg */
    float calm_s;     /* time inside the settle band */
    float elapsed_s;  /* time since this recovery began */
} recovery_state_t;

/* Power-on: alpha_avg starts at alpha_avg_deg (the firmware assumes mid-stroke). */
void recovery_init(recovery_state_t *r, float alpha_avg_deg);

/* Begin a new recovery: the settle and give-up clocks restart, alpha_avg is kept. */
void recovery_restart(recovery_state_t *r);

/* One controller period toward setpoint_m; actuator_deg is the gear angle now (feeds alpha_avg).
   Returns the commanded gear angle; *settled / *gave_up as recovery_settled / recovery_gave_up. */
float recovery_step(recovery_state_t *r, const recovery_params_t *p, float depth_m, float velocity_mps,
                    float setpoint_m, float actuator_deg, float dt_s, bool *settled, bool *gave_up);

float recovery_alpha_avg_deg(const recovery_state_t *r);

#endif
