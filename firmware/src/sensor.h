/* The MS5803-01BA pressure sensor for the emulated board: simulator/sensor.py in C (noise, LSB, range). */
#ifndef SENSOR_H
#define SENSOR_H

#include "rng.h"

typedef struct {
    double surface_pressure_pa, water_density_kgpm3, gravity_mps2;
    double noise_pa, lsb_pa, min_pa, max_pa;
} sensor_params_t;

void   sensor_hardware_params(sensor_params_t *p);
/* Absolute pressure as the sensor reports it at depth_m; draws from r (Box-Muller as learning/rng.py). */
double sensor_read_pa(const sensor_params_t *p, rng_t *r, double depth_m);

#endif
