/* Fixed figures of the agent's hardware and firmware (the F-sourced values of simulator/parameters.py). */
#ifndef CONFIG_H
#define CONFIG_H

#define CFG_FIRMWARE_MAJOR 1u
#define CFG_FIRMWARE_MINOR 1u
#define CFG_FIRMWARE_PATCH 0u
#ifndef CFG_AGENT_NAME
#define CFG_AGENT_NAME "diving-agent"
#endif

#define CFG_ALPHA_MAX_DEG 130.0f         /* gear output range 0..130 deg */
#define CFG_NEUTRAL_DEG 65.0f            /* mid-stroke, assumed before alpha_avg is learned */
#define CFG_WATER_DENSITY_KGPM3 1000.0f
#define CFG_GRAVITY_MPS2 9.81f
#define CFG_RECOVERY_PERIOD_US 25000u    /* recovery controller period */
#define CFG_IDLE_SAMPLE_US 1000000u      /* SAMPLE at 1 Hz in IDLE */
#define CFG_SURFACE_DEPTH_M 0.02f        /* SURFACING ends shallower than this */
#define CFG_START_DEPTH_FRACTION 0.95f   /* recovery start depth ~ U(+/- 0.95 z_tol) around the target */
#define CFG_HOVER_MAX_DEPTH_M 2.5f
/* Value iteration per step (recovery period 25 ms): the per-state learners run whole sweeps (~60 000
   instructions each at S = 101); the shared model runs state backups (a sweep is S - 1 of them, up to ~9 000
   instructions each with every slot of both types filled), so a step's planning is bounded whatever S is
   (docs/firmware.md: measured in QEMU). */
#define CFG_PLAN_SWEEPS_PER_STEP 2u
#define CFG_PLAN_BACKUPS_PER_STEP 100u
#define CFG_VEL_DIFF_MAX_STEPS 16u       /* depth history for the k-step velocity (vel_diff_steps <= 16) */

#define CFG_OBSERVER_RHO_MPS 2.5f
#define CFG_OBSERVER_TAU_S 0.2f
#define CFG_OBSERVER_PHI_M 0.5f

#define CFG_RECOVERY_LAMBDA_PER_S 0.4f
#define CFG_RECOVERY_PHI_MPS 0.5f
#define CFG_RECOVERY_GAIN_DEG 65.0f
#define CFG_RECOVERY_AVG_TIME_S 10.0f
#define CFG_RECOVERY_NEAR_GAIN_DEG 3.0f  /* inner layer: takes up the gear backlash (hardware preset) */
#define CFG_RECOVERY_NEAR_PHI_MPS 0.01f
#define CFG_SETTLE_DEPTH_M 0.01f
#define CFG_SETTLE_VELOCITY_MPS 0.01f
#define CFG_SETTLE_TIME_S 6.25f
#define CFG_GIVE_UP_S 100.0f

#endif
