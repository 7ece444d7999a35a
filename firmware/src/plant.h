/* The simulated water for the emulated board: simulator/plant_kernel.py in C (hardware preset physics).

   Not part of the on-board program: it stands in for the world, so it computes in double like the
   Python reference (the differential test compares the two on the same inputs). */
#ifndef PLANT_H
#define PLANT_H

#include "rng.h"

typedef struct {
    double mass_kg, added_mass_kg, water_density_kgpm3, gravity_mps2, trim_error_fraction;
    double compressibility_m3pm, drag_kgpm, floor_depth_m;
    double stroke_volume_m3, alpha_max_deg, alpha_rate_dps, substep_s;
    /* The real robot's imperfections (parameters.py, docs/robust-plant.md); 0 = the ideal plant. */
    double backlash_deg, dead_band_deg, pressure_lag_s, control_jitter_s;
} plant_params_t;

/* simulator/plant/kernel.py's state layout, field for field. */
typedef struct {
    double z_m;          /* depth, positive down */
    double zdot_mps;     /* velocity, positive down */
    double alpha_deg;    /* gear output angle */
    double motor_deg;    /* stepper side of the gear train (within half the backlash of alpha_deg) */
    double sensed_z_m;   /* depth the pressure port sees (lags z_m by pressure_lag_s) */
    double clock_s;      /* plant time since the start */
    double noise_pa;     /* the sensor's AR(1) noise state */
    double last_read_s;  /* plant time of the last reading */
} plant_state_t;

/* The `hardware` preset of simulator/parameters.py. */
void   plant_hardware_params(plant_params_t *p);
/* Gear angle of neutral buoyancy (parameters.neutral_alpha_deg). */
double plant_neutral_alpha_deg(const plant_params_t *p);
/* Advance dt_s in sub-steps of at most substep_s, command held (semi-implicit Euler). */
void   plant_step(plant_state_t *x, const plant_params_t *p, double alpha_cmd_deg, double dt_s);
/* Put the agent somewhere at once: gear train closed, the port at the new depth (kernel.py plant_place). */
void   plant_place(plant_state_t *x, double depth_m, double velocity_mps, double alpha_deg);
/* How long a control step of nominal period_s lasts: +/- control_jitter_s, uniform; draws only when > 0. */
double plant_jittered_period_s(const plant_params_t *p, rng_t *r, double period_s);

#endif
