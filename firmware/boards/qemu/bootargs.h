/* Boot arguments that simulator/firmware_qemu.py writes into RAM with QEMU's generic loader. */
#ifndef QEMU_BOOTARGS_H
#define QEMU_BOOTARGS_H

#include <stdbool.h>
#include <stdint.h>

#include "plant.h"
#include "sensor.h"

#define BOOTARGS_MAGIC 0x41524753u  /* "ARGS" */
#define BOOTARGS_KEY_BYTES 32u      /* HMAC-SHA256 key */
#define BOOTARGS_BYTES 512u         /* the block mps2_an386.ld reserves below the stack */

/* The plant figures the loader may write, in this order, each a double: simulator/parameters.py's names, so a
   plant file reaches the C plant and sensor without a rebuild. firmware_qemu.py's PLANT_FIELDS is the same list
   (tests/firmware/test_qemu_plant.py compares the two). */
#define BOOTARGS_PLANT(X) \
    X(mass_kg) X(added_mass_kg) X(water_density_kgpm3) X(gravity_mps2) X(trim_error_fraction) \
    X(compressibility_m3pm) X(drag_kgpm) X(floor_depth_m) X(stroke_volume_m3) X(alpha_max_deg) \
    X(alpha_rate_dps) X(substep_s) X(backlash_deg) X(dead_band_deg) X(control_jitter_s) \
    X(surface_pressure_pa) X(pressure_noise_pa) X(pressure_lsb_pa) X(pressure_min_pa) X(pressure_max_pa) \
    X(pressure_bias_pa) X(pressure_drift_pa_per_s) X(pressure_lag_s) X(pressure_noise_corr_s) \
    X(depth_scale_error)

#define BOOTARGS_PLANT_INDEX(name) BOOTARGS_PLANT_##name,
enum { BOOTARGS_PLANT(BOOTARGS_PLANT_INDEX) BOOTARGS_PLANT_COUNT };
#undef BOOTARGS_PLANT_INDEX

typedef struct {
    uint32_t magic;
    uint32_t node_id;      /* 0: the board's default */
    uint32_t seed_lo;      /* sensor noise and entropy stream */
    uint32_t seed_hi;
    uint32_t speed_milli;  /* agent time per real time x 1000; 0 = as fast as the CPU goes */
    uint32_t bench;        /* 1: print instruction counts on UART1 (run with -icount shift=0) */
    uint32_t has_key;      /* 1: key holds the signing key, commands must be signed */
    uint8_t  key[BOOTARGS_KEY_BYTES];
    uint32_t has_plant;    /* 1: plant holds every figure of BOOTARGS_PLANT; else the hardware preset's */
    double   plant[BOOTARGS_PLANT_COUNT];  /* at byte 64 */
} bootargs_raw_t;

typedef struct {
    uint32_t node_id;
    uint64_t seed;
    uint32_t speed_milli;
    uint32_t bench;
    bool has_key;
    uint8_t key[BOOTARGS_KEY_BYTES];
    bool has_plant;
    double plant[BOOTARGS_PLANT_COUNT];
} bootargs_t;

/* The arguments, or defaults (seed 1, full speed, no bench, the built-in plant) when QEMU wrote none. */
const bootargs_t *bootargs(void);
/* The hardware preset's plant and sensor with the boot arguments' plant figures, when there are some. */
void bootargs_plant(plant_params_t *plant, sensor_params_t *sensor);

#endif
