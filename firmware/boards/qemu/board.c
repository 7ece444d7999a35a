/* The hardware layer of the emulated agent (QEMU mps2-an386): the C plant and sensor stand in for the
   water, the link is UART0 (bridged by QEMU to TCP), the log is a RAM array.

   Agent time is plant time: it advances by each step's period, so the agent runs as fast as the
   emulated CPU allows, or paced against the real clock by the boot argument speed (1 = real time).
   Link time is the real clock (CMSDK timer 0), as decisions.md asks of an agent faster than real time. */
#include <string.h>

#include "agent.h"
#include "bench.h"
#include "bootargs.h"
#include "hal.h"
#include "learner.h"
#include "modes.h"
#include "plant.h"
#include "rng.h"
#include "sensor.h"
#include "timer.h"
#include "uart.h"

#define LOG_BYTES (512u * 1024u)  /* the two M24M02 EEPROMs' 512 KiB, in the emulator's RAM */
#define NV_BYTES 64u
#define ENDURANCE_S 7200.0        /* simulator/agent_mission.py: a 1S LiPo lasts about 2 h */
#define NODE_ID_DEFAULT 0x51454D55u  /* "QEMU" */
#define BATTERY_POINTS 7u

static struct {
    plant_params_t plant;
    plant_state_t x;
    double alpha_cmd_deg;
    sensor_params_t sensor;
    rng_t sensor_rng;
    rng_t jitter_rng;  /* its own stream: a plant without jitter draws exactly what it drew before */
    rng_t entropy;
    uint64_t t_us;
    double charge_fraction;
} board;

static uint8_t log_ram[LOG_BYTES];
static uint8_t nv_ram[NV_BYTES];

/* 1S LiPo open-circuit voltage by state of charge (simulator/agent_mission.py BatteryParams.curve). */
static const float battery_soc[BATTERY_POINTS] = {0.0f, 0.05f, 0.10f, 0.20f, 0.50f, 0.80f, 1.0f};
static const float battery_v[BATTERY_POINTS] = {3.40f, 3.55f, 3.65f, 3.72f, 3.82f, 3.98f, 4.20f};

uint64_t hal_time_us(void)
{
    return board.t_us;
}

uint64_t hal_link_time_us(void)
{
    return timer_real_us();
}

float hal_pressure_pa(void)
{
    return (float)sensor_sense_pa(&board.sensor, &board.sensor_rng, &board.x);
}

void hal_stepper_set_cmd_deg(float deg)
{
    double cmd = (double)deg;
    board.alpha_cmd_deg = cmd < 0.0 ? 0.0 : (cmd > board.plant.alpha_max_deg ? board.plant.alpha_max_deg : cmd);
}

float hal_stepper_deg(void)
{
    /* The motor side of the gear train, as the Teensy counts its steps: the output angle behind the
       backlash stays inside the plant (a real robot cannot read it). */
    return (float)board.x.motor_deg;
}

float hal_battery_v(void)
{
    float soc = (float)board.charge_fraction;
    for (uint32_t i = 1u; i < BATTERY_POINTS; i++) {
        if (soc <= battery_soc[i]) {
            float w = (soc - battery_soc[i - 1u]) / (battery_soc[i] - battery_soc[i - 1u]);
            return battery_v[i - 1u] + (battery_v[i] - battery_v[i - 1u]) * w;
        }
    }
    return battery_v[BATTERY_POINTS - 1u];
}

size_t hal_link_read(uint8_t *buf, size_t cap)
{
    return uart0_read(buf, cap);
}

void hal_link_write(const uint8_t *buf, size_t n)
{
    uart0_write(buf, n);
}

bool hal_log_read(uint32_t addr, uint8_t *buf, size_t n)
{
    if (addr > LOG_BYTES || n > LOG_BYTES - addr) {
        return false;
    }
    memcpy(buf, &log_ram[addr], n);
    return true;
}

bool hal_log_write(uint32_t addr, const uint8_t *buf, size_t n)
{
    if (addr > LOG_BYTES || n > LOG_BYTES - addr) {
        return false;
    }
    memcpy(&log_ram[addr], buf, n);
    return true;
}

uint32_t hal_log_capacity_bytes(void)
{
    return LOG_BYTES;
}

bool hal_nv_read(uint8_t *buf, size_t n)
{
    if (n > NV_BYTES) {
        return false;
    }
    memcpy(buf, nv_ram, n);
    return true;
}

bool hal_nv_write(const uint8_t *buf, size_t n)
{
    if (n > NV_BYTES) {
        return false;
    }
    memcpy(nv_ram, buf, n);
    return true;
}

uint32_t hal_entropy(void)
{
    /* The boot seed's stream, stirred with the real clock's low bits. */
    return (uint32_t)(rng_next_u64(&board.entropy) >> 32) ^ timer_raw();
}

bool hal_sim_place(float depth_m)
{
    /* The paper's simulated restart: at rest at depth_m, gear at true neutral. */
    double neutral = plant_neutral_alpha_deg(&board.plant);
    plant_place(&board.x, (double)depth_m, 0.0, neutral);
    board.alpha_cmd_deg = neutral;
    return true;
}

static void board_init(void)
{
    const bootargs_t *args = bootargs();
    bootargs_plant(&board.plant, &board.sensor);  /* the hardware preset, or the plant file QEMU was given */
    /* At the surface, gear at mid-stroke (the firmware's assumed neutral), as simulator/onboard_hw.py. */
    plant_place(&board.x, 0.0, 0.0, board.plant.alpha_max_deg / 2.0);
    board.alpha_cmd_deg = board.x.alpha_deg;
    rng_seed(&board.sensor_rng, args->seed ^ 0x5EED5EED5EED5EEDull);
    rng_seed(&board.jitter_rng, args->seed ^ 0x717E717E717E717Eull);
    rng_seed(&board.entropy, args->seed);
    board.charge_fraction = 1.0;
    board.t_us = 0u;
}

/* Advance the plant and the agent's clock by one step of nominal dt_us; returns how long it really lasted.

   With control_jitter_s the step lasts dt_us +/- up to it, as a Teensy's step does when planning slices and
   link interrupts stretch it: the plant and the agent's clock both see the real length. */
static uint32_t advance(uint32_t dt_us)
{
    double dt_s = plant_jittered_period_s(&board.plant, &board.jitter_rng, (double)dt_us * 1e-6);
    dt_us = (uint32_t)(dt_s * 1e6 + 0.5);
    dt_s = (double)dt_us * 1e-6;
    plant_step(&board.x, &board.plant, board.alpha_cmd_deg, dt_s);
    board.charge_fraction -= dt_s / ENDURANCE_S;
    board.charge_fraction = board.charge_fraction > 0.0 ? board.charge_fraction : 0.0;
    board.t_us += dt_us;
    return dt_us;
}

int main(void)
{
    uart_init();
    timer_init();
    board_init();
    const bootargs_t *args = bootargs();
    if (args->bench != 0u) {
        bench_paint_stack();
        bench_calibrate();
    }
    agent_init(args->node_id != 0u ? args->node_id : NODE_ID_DEFAULT, args->has_key ? args->key : NULL);
    uint64_t due_real_us = timer_real_us();
    for (;;) {
        if (uart2_link_up()) {
            agent_link_up();  /* SPEC 1.1: a new TCP connection resets sequence tracking and gets a HELLO */
        }
        agent_poll_link();
        if (args->speed_milli != 0u) {
            /* Paced: the next step waits for its real time, reading the link meanwhile. */
            while (timer_real_us() < due_real_us) {
                agent_poll_link();
                timer_idle();
            }
        }
        uint8_t mode = modes_mode();
        bool planning = learner_planning();
        uint32_t start = timer_raw();
        uint32_t dt_us = agent_step();
        if (args->bench != 0u) {
            bench_record(mode, planning, timer_raw() - start, dt_us);
        }
        dt_us = advance(dt_us);
        if (args->speed_milli != 0u) {
            due_real_us += (uint64_t)dt_us * 1000u / args->speed_milli;
        }
    }
}
