/* simulator/plant/kernel.py in C: z'' = a0 + a_alpha alpha + a_z z - a_drag z'|z'|, semi-implicit Euler. */
#include "plant.h"

#include <math.h>

void plant_hardware_params(plant_params_t *p)
{
    /* simulator/parameters.py PlantParams defaults with the `hardware` preset's trim error. */
    p->mass_kg = 0.3793;
    p->added_mass_kg = 0.10;
    p->water_density_kgpm3 = 1000.0;
    p->gravity_mps2 = 9.81;
    p->trim_error_fraction = 0.005;
    p->compressibility_m3pm = 0.0;
    p->drag_kgpm = 1.0;
    p->floor_depth_m = 10.0;
    p->stroke_volume_m3 = 14.44e-6;
    p->alpha_max_deg = 130.0;
    p->alpha_rate_dps = 35.2;
    p->substep_s = 0.005;
    p->backlash_deg = 0.0;
    p->dead_band_deg = 0.0;
    p->pressure_lag_s = 0.0;
    p->control_jitter_s = 0.0;
}

void plant_place(plant_state_t *x, double depth_m, double velocity_mps, double alpha_deg)
{
    x->z_m = depth_m;
    x->zdot_mps = velocity_mps;
    x->alpha_deg = alpha_deg;
    x->motor_deg = alpha_deg;
    x->sensed_z_m = depth_m;
}

double plant_jittered_period_s(const plant_params_t *p, rng_t *r, double period_s)
{
    if (p->control_jitter_s > 0.0) {
        double u = (double)rng_draw53(r) * (1.0 / 9007199254740992.0);
        return period_s + p->control_jitter_s * (2.0 * u - 1.0);
    }
    return period_s;
}

double plant_neutral_alpha_deg(const plant_params_t *p)
{
    double fixed_volume_m3 = p->mass_kg / p->water_density_kgpm3 * (1.0 + p->trim_error_fraction);
    double v_adj_m3 = p->mass_kg / p->water_density_kgpm3 - fixed_volume_m3;
    return p->alpha_max_deg * (v_adj_m3 / p->stroke_volume_m3 + 0.5);
}

static double clamp(double x, double lo, double hi)
{
    return x < lo ? lo : (x > hi ? hi : x);
}

void plant_step(plant_state_t *x, const plant_params_t *p, double alpha_cmd_deg, double dt_s)
{
    long n_sub = (long)ceil(dt_s / p->substep_s - 1e-9);
    n_sub = n_sub < 1 ? 1 : n_sub;
    double h = dt_s / (double)n_sub;
    double max_move_deg = p->alpha_rate_dps * h;
    double target_deg = clamp(alpha_cmd_deg, 0.0, p->alpha_max_deg);
    /* force_coefficients, in the order plant_kernel.py computes them */
    double inertia_kg = p->mass_kg + p->added_mass_kg;
    double rho_g = p->water_density_kgpm3 * p->gravity_mps2;
    double fixed_volume_m3 = p->mass_kg / p->water_density_kgpm3 * (1.0 + p->trim_error_fraction);
    double net_weight_n = p->mass_kg * p->gravity_mps2 - rho_g * (fixed_volume_m3 - 0.5 * p->stroke_volume_m3);
    double a0 = net_weight_n / inertia_kg;
    double a_alpha = -rho_g * p->stroke_volume_m3 / p->alpha_max_deg / inertia_kg;
    double a_z = rho_g * p->compressibility_m3pm / inertia_kg;
    double a_drag = p->drag_kgpm / inertia_kg;
    double h_a0 = h * a0, h_alpha = h * a_alpha, h_z = h * a_z, h_drag = h * a_drag;
    int compressible = a_z != 0.0;
    double z = x->z_m, zdot = x->zdot_mps, alpha = x->alpha_deg;
    int real_gear = p->backlash_deg > 0.0 || p->dead_band_deg > 0.0;
    double motor = real_gear ? x->motor_deg : alpha;
    double half_dead = 0.5 * p->dead_band_deg, half_lash = 0.5 * p->backlash_deg;
    int lagged = p->pressure_lag_s > 0.0;
    double sensed = x->sensed_z_m;
    double lag_gain = lagged ? 1.0 - exp(-h / p->pressure_lag_s) : 1.0;
    for (long i = 0; i < n_sub; i++) {
        if (real_gear) {
            /* The stepper stops within half the dead band; the output waits for the lost motion. */
            double error = target_deg - motor;
            if (fabs(error) > half_dead) {
                motor += clamp(error, -max_move_deg, max_move_deg);
            }
            alpha = clamp(alpha, motor - half_lash, motor + half_lash);
        } else {
            /* The stepper moves toward the command at its top rate and stops at the end stops. */
            alpha += clamp(target_deg - alpha, -max_move_deg, max_move_deg);
        }
        double push = h_a0 + h_alpha * alpha;
        if (compressible) {
            push += h_z * z;
        }
        zdot = (zdot + push) - (h_drag * zdot) * fabs(zdot);
        z += h * zdot;
        /* Free surface and floor: the hull cannot leave the water column. */
        if (z < 0.0) {
            z = 0.0;
            zdot = zdot > 0.0 ? zdot : 0.0;
        } else if (z > p->floor_depth_m) {
            z = p->floor_depth_m;
            zdot = zdot < 0.0 ? zdot : 0.0;
        }
        if (lagged) {
            sensed += lag_gain * (z - sensed);
        }
    }
    x->z_m = z;
    x->zdot_mps = zdot;
    x->alpha_deg = alpha;
    x->motor_deg = real_gear ? motor : alpha;
    x->sensed_z_m = lagged ? sensed : z;
    x->clock_s += dt_s;
}
