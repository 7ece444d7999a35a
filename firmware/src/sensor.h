/* The MS5803-01BA pressure sensor for the emulated board: simulator/plant/sensor.py in C (noise, LSB, range). */
#ifndef SENSOR_H
#define SENSOR_H

#include "plant.h"
#include "rng.h"

typedef struct {
    double surface_pressure_pa, water_density_kgpm3, gravity_mps2;
    double noise_pa, lsb_pa, min_pa, max_pa;
    /* The real sensor's imperfections (parameters.py, docs/robust-plant.md); 0 = the ideal sensor. The port's
       lag is the plant's (plant_params_t.pressure_lag_s): pass it here too so the reading takes the lagged depth. */
    double bias_pa, drift_pa_per_s, noise_corr_s, depth_scale_error, lag_s;
} sensor_params_t;

void   sensor_hardware_params(sensor_params_t *p);
/* Absolute pressure as the sensor reports it at depth_m; draws from r (Box-Muller as learning/rng.py). */
double sensor_read_pa(const sensor_params_t *p, rng_t *r, double depth_m);
/* The real sensor's reading for a plant state (sensor.py sense_pressure_kernel): bias, drift, lag, scale, AR(1)
   noise; updates the noise state in x. With every imperfection 0 it draws and returns what sensor_read_pa does. */
double sensor_sense_pa(const sensor_params_t *p, rng_t *r, plant_state_t *x);

#endif
