/* The simulated water for the emulated board: simulator/plant_kernel.py in C (hardware preset physics).

   Not part of the on-board program: it stands in for the world, so it computes in double like the
   Python reference (the differential test compares the two on the same inputs). */
#ifndef PLANT_H
#define PLANT_H

typedef struct {
    double mass_kg, added_mass_kg, water_density_kgpm3, gravity_mps2, trim_error_fraction;
    double compressibility_m3pm, drag_kgpm, floor_depth_m;
    double stroke_volume_m3, alpha_max_deg, alpha_rate_dps, substep_s;
} plant_params_t;

typedef struct {
    double z_m;          /* depth, positive down */
    double zdot_mps;     /* velocity, positive down */
    double alpha_deg;    /* gear output angle */
} plant_state_t;

/* The `hardware` preset of simulator/parameters.py. */
void   plant_hardware_params(plant_params_t *p);
/* Gear angle of neutral buoyancy (parameters.neutral_alpha_deg). */
double plant_neutral_alpha_deg(const plant_params_t *p);
/* Advance dt_s in sub-steps of at most substep_s, command held (semi-implicit Euler). */
void   plant_step(plant_state_t *x, const plant_params_t *p, double alpha_cmd_deg, double dt_s);

#endif
