/* simulator/sensor.py in C: P = P0 + rho g z + noise, quantised to the LSB, clipped to the range. */
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

double sensor_read_pa(const sensor_params_t *p, rng_t *r, double depth_m)
{
    double pressure_pa = p->surface_pressure_pa + p->water_density_kgpm3 * p->gravity_mps2 * depth_m;
    pressure_pa += p->noise_pa * normal(r);
    /* np.round rounds half to even, as rint in the default rounding mode */
    pressure_pa = rint(pressure_pa / p->lsb_pa) * p->lsb_pa;
    return pressure_pa < p->min_pa ? p->min_pa : (pressure_pa > p->max_pa ? p->max_pa : pressure_pa);
}
