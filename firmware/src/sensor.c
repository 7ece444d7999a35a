/* simulator/plant/sensor.py in C: P = P0 + rho g z + noise, quantised to the LSB, clipped to the range. */
#include "sensor.h"

#include <math.h>

#define TWO_POW_MINUS_53 (1.0 / 9007199254740992.0)
#define TWO_PI 6.283185307179586

void sensor_hardware_params(sensor_params_t *p)
{
    p->surface_pressure_pa = 101325.0;
    p->water_density_kgpm3 = 1000.0;
    p->gravity_mps2 = 9.81;
    p->noise_pa = 6.5;
    p->lsb_pa = 1.0;
    p->min_pa = 1000.0;
    p->max_pa = 130000.0;
    p->bias_pa = 0.0;
    p->drift_pa_per_s = 0.0;
    p->noise_corr_s = 0.0;
    p->depth_scale_error = 0.0;
    p->lag_s = 0.0;
}

static double uniform(rng_t *r)
{
    return (double)rng_draw53(r) * TWO_POW_MINUS_53;
}

/* Box-Muller, the second variate dropped (learning/rng.py normal). */
static double normal(rng_t *r)
{
    double u1 = 1.0 - uniform(r);
    double u2 = uniform(r);
    return sqrt(-2.0 * log(u1)) * cos(TWO_PI * u2);
}

static double quantise_clip(const sensor_params_t *p, double pressure_pa)
{
    /* np.round rounds half to even, as rint in the default rounding mode */
    pressure_pa = rint(pressure_pa / p->lsb_pa) * p->lsb_pa;
    return pressure_pa < p->min_pa ? p->min_pa : (pressure_pa > p->max_pa ? p->max_pa : pressure_pa);
}

double sensor_read_pa(const sensor_params_t *p, rng_t *r, double depth_m)
{
    double pressure_pa = p->surface_pressure_pa + p->water_density_kgpm3 * p->gravity_mps2 * depth_m;
    pressure_pa += p->noise_pa * normal(r);
    return quantise_clip(p, pressure_pa);
}

double sensor_sense_pa(const sensor_params_t *p, rng_t *r, plant_state_t *x)
{
    double depth_m = p->lag_s > 0.0 ? x->sensed_z_m : x->z_m;
    if (p->depth_scale_error != 0.0) {
        depth_m *= 1.0 + p->depth_scale_error;
    }
    double pressure_pa = p->surface_pressure_pa + p->water_density_kgpm3 * p->gravity_mps2 * depth_m;
    if (p->bias_pa != 0.0 || p->drift_pa_per_s != 0.0) {
        pressure_pa += p->bias_pa + p->drift_pa_per_s * x->clock_s;
    }
    if (p->noise_corr_s > 0.0) {
        /* AR(1) over the time since the last reading: the same stationary spread at any reading rate. */
        double keep = exp(-(x->clock_s - x->last_read_s) / p->noise_corr_s);
        x->noise_pa = keep * x->noise_pa + sqrt(1.0 - keep * keep) * p->noise_pa * normal(r);
        x->last_read_s = x->clock_s;
        pressure_pa += x->noise_pa;
    } else {
        pressure_pa += p->noise_pa * normal(r);
    }
    return quantise_clip(p, pressure_pa);
}
