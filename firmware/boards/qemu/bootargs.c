/* Reads the boot arguments block the linker script reserves below the stack. */
#include "bootargs.h"

#include <stddef.h>

/* C99 has no static assertion: a negative array size stops the build if the block outgrows its room. */
typedef char bootargs_fit_check[sizeof(bootargs_raw_t) <= BOOTARGS_BYTES ? 1 : -1];
typedef char bootargs_layout_check[offsetof(bootargs_raw_t, plant) == 64u ? 1 : -1];

extern const bootargs_raw_t BOOTARGS_ADDR;

static bootargs_t args;
static int loaded;

const bootargs_t *bootargs(void)
{
    if (!loaded) {
        const volatile bootargs_raw_t *raw = &BOOTARGS_ADDR;
        if (raw->magic == BOOTARGS_MAGIC) {
            args.node_id = raw->node_id;
            args.seed = ((uint64_t)raw->seed_hi << 32) | raw->seed_lo;
            args.speed_milli = raw->speed_milli;
            args.bench = raw->bench;
            args.has_key = raw->has_key == 1u;
            for (uint32_t i = 0u; i < BOOTARGS_KEY_BYTES; i++) {
                args.key[i] = raw->key[i];
            }
            args.has_plant = raw->has_plant == 1u;
            for (uint32_t i = 0u; i < (uint32_t)BOOTARGS_PLANT_COUNT; i++) {
                args.plant[i] = raw->plant[i];
            }
        } else {
            args.seed = 1u;
        }
        loaded = 1;
    }
    return &args;
}

void bootargs_plant(plant_params_t *plant, sensor_params_t *sensor)
{
    plant_hardware_params(plant);
    sensor_hardware_params(sensor);
    const bootargs_t *a = bootargs();
    if (!a->has_plant) {
        return;
    }
    /* The figures were checked on the host (simulator/parameters.py validate) before QEMU started. */
#define FIGURE(name) (a->plant[BOOTARGS_PLANT_##name])
    plant->mass_kg = FIGURE(mass_kg);
    plant->added_mass_kg = FIGURE(added_mass_kg);
    plant->water_density_kgpm3 = FIGURE(water_density_kgpm3);
    plant->gravity_mps2 = FIGURE(gravity_mps2);
    plant->trim_error_fraction = FIGURE(trim_error_fraction);
    plant->compressibility_m3pm = FIGURE(compressibility_m3pm);
    plant->drag_kgpm = FIGURE(drag_kgpm);
    plant->floor_depth_m = FIGURE(floor_depth_m);
    plant->stroke_volume_m3 = FIGURE(stroke_volume_m3);
    plant->alpha_max_deg = FIGURE(alpha_max_deg);
    plant->alpha_rate_dps = FIGURE(alpha_rate_dps);
    plant->substep_s = FIGURE(substep_s);
    plant->backlash_deg = FIGURE(backlash_deg);
    plant->dead_band_deg = FIGURE(dead_band_deg);
    plant->pressure_lag_s = FIGURE(pressure_lag_s);
    plant->control_jitter_s = FIGURE(control_jitter_s);
    sensor->surface_pressure_pa = FIGURE(surface_pressure_pa);
    sensor->water_density_kgpm3 = FIGURE(water_density_kgpm3);
    sensor->gravity_mps2 = FIGURE(gravity_mps2);
    sensor->noise_pa = FIGURE(pressure_noise_pa);
    sensor->lsb_pa = FIGURE(pressure_lsb_pa);
    sensor->min_pa = FIGURE(pressure_min_pa);
    sensor->max_pa = FIGURE(pressure_max_pa);
    sensor->bias_pa = FIGURE(pressure_bias_pa);
    sensor->drift_pa_per_s = FIGURE(pressure_drift_pa_per_s);
    sensor->noise_corr_s = FIGURE(pressure_noise_corr_s);
    sensor->depth_scale_error = FIGURE(depth_scale_error);
    sensor->lag_s = FIGURE(pressure_lag_s);  /* the port's lag is the plant's: the reading takes the lagged depth */
#undef FIGURE
}
