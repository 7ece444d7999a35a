"""Compiled episode logic shared by DivingEnv and the study runner: start, one learner step, reward."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.acting import reward_kernel, state_index_kernel, step_size_kernel
from learning.config import MAX_VELOCITY_DIFF_STEPS
from learning.rng import uniform
from learning.shared import raw_cell_kernel
from learning.spec import KernelSpec
from simulator.plant.kernel import ALPHA, MOTOR, PLANT_SIZE, ZDOT, Z, jittered_period_s, plant_place, plant_step
from simulator.plant.observer import observer_update_kernel
from simulator.plant.recovery import AVG, recovery_gave_up, recovery_init, recovery_settled, recovery_update_kernel
from simulator.plant.sensor import depth_from_pressure_kernel, sense_pressure_kernel

# Layout of the environment state array: plant, command, observer, recovery, bookkeeping.
E_Z, E_ZDOT, E_ALPHA = Z, ZDOT, ALPHA  # plant (the first PLANT_SIZE entries, plant_step's layout)
E_MOTOR = MOTOR  # the stepper side of the gear train: the only angle the agent knows (it counts its steps)
E_PLANT_END = PLANT_SIZE
E_CMD = PLANT_SIZE  # alpha_cmd, deg
E_CENTER = E_CMD + 1  # centre of the learner's actuator window (alpha_avg at hand-over), deg
E_OBS_X1, E_OBS_X2 = E_CMD + 2, E_CMD + 3  # observer
E_REC_AVG, E_REC_CALM, E_REC_ELAPSED = E_CMD + 4, E_CMD + 5, E_CMD + 6  # recovery controller
E_STEPS = E_CMD + 7  # learner steps taken in the current episode
E_DEPTH_MEAS = E_CMD + 8  # last measured depth, m
E_VEL_EST = E_CMD + 9  # velocity the learner sees, m/s
E_RECOVERY_S = E_CMD + 10  # time the recovery controller needed before this episode, s
E_STARTED = E_CMD + 11  # 1 after the first reset (the plant state carries over between episodes)
E_RING_POS = E_CMD + 12  # next slot of the depth ring (the learner's own k-step depth difference)
E_RING = E_CMD + 13  # measured depths of the last MAX_VELOCITY_DIFF_STEPS control steps
E_FILT_Z = E_RING + MAX_VELOCITY_DIFF_STEPS  # the learner's velocity filter: depth, m
E_FILT_V = E_FILT_Z + 1  # velocity, m/s
E_FILT_B = E_FILT_Z + 2  # acceleration bias, m/s^2
E_LAST_ACTION = E_FILT_Z + 3  # the learner's last action this episode (-1 before its first)
E_HELD = E_FILT_Z + 4  # 1 if the last step was a hold (LearnerConfig.hold_depth_m), else 0
E_NEUTRAL = E_FILT_Z + 5  # the neutral the learner finds (LearnerConfig.neutral_gain), deg; 0 before its first
ENV_SIZE = E_FILT_Z + 6
_MAX_RECOVERY_ATTEMPTS = 20


@njit(cache=True, error_model="numpy")
def new_env_state(spec: KernelSpec) -> NDArray[np.float64]:
    """An environment before its first episode: at the surface, gear at mid-stroke."""
    env = np.zeros(ENV_SIZE)
    plant_place(env[:E_PLANT_END], 0.0, 0.0, spec.alpha_max_deg / 2.0)
    env[E_CMD] = env[E_ALPHA]
    env[E_CENTER] = env[E_ALPHA]
    env[E_REC_AVG] = env[E_ALPHA]
    return env


@njit(cache=True, error_model="numpy", inline="always")
def neutral_alpha_kernel(spec: KernelSpec) -> float:
    """Gear angle of neutral buoyancy at the surface (same formula as parameters.neutral_alpha_deg)."""
    fixed_m3 = spec.mass_kg / spec.water_density_kgpm3 * (1.0 + spec.trim_error_fraction)
    v_adj_m3 = spec.mass_kg / spec.water_density_kgpm3 - fixed_m3
    return spec.alpha_max_deg * (v_adj_m3 / spec.stroke_volume_m3 + 0.5)


@njit(cache=True, error_model="numpy", inline="always")
def measure_kernel(env: NDArray[np.float64], dt_s: float, spec: KernelSpec, rng_state: NDArray[np.uint64]) -> None:
    """Read the sensor into the measured depth; update the observer and the velocity the learner sees."""
    pressure_pa = sense_pressure_kernel(env[:E_PLANT_END], spec, rng_state)
    env[E_DEPTH_MEAS] = depth_from_pressure_kernel(pressure_pa, spec)
    obs = env[E_OBS_X1:E_OBS_X2 + 1]
    estimate = observer_update_kernel(obs, env[E_DEPTH_MEAS], dt_s, spec)
    env[E_VEL_EST] = estimate if spec.use_observer else env[E_ZDOT]


@njit(cache=True, error_model="numpy")
def _recover(
    env: NDArray[np.float64], start_depth_m: float, spec: KernelSpec, rng_state: NDArray[np.uint64]
) -> bool:
    """Run the recovery controller to start_depth_m; True once settled, False if it gave up."""
    rec = env[E_REC_AVG:E_REC_ELAPSED + 1]
    recovery_init(rec, rec[AVG])
    plant = env[:E_PLANT_END]
    dt = spec.recovery_period_s
    while True:
        measure_kernel(env, dt, spec, rng_state)
        env[E_CMD] = recovery_update_kernel(
            rec, env[E_DEPTH_MEAS], env[E_OBS_X2], env[E_MOTOR], start_depth_m, dt, spec
        )
        plant_step(plant, env[E_CMD], dt, spec)
        env[E_RECOVERY_S] += dt
        if recovery_settled(rec, spec):
            return True
        if recovery_gave_up(rec, spec):
            return False


@njit(cache=True, error_model="numpy")
def episode_reset_kernel(
    env: NDArray[np.float64],
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    rng_state: NDArray[np.uint64],
) -> int:
    """Start an episode at a random depth of the learning region; returns the first state index."""
    env[E_STEPS] = 0.0
    env[E_RECOVERY_S] = 0.0
    env[E_LAST_ACTION] = -1.0
    env[E_HELD] = 0.0
    half_m = spec.start_depth_fraction * lspec.z_tol_m
    if spec.start_with_recovery:
        if env[E_STARTED] == 0.0:
            env[E_OBS_X1] = env[E_Z]
            env[E_OBS_X2] = 0.0
        # The controller hands over within settle_depth_m of its goal: keep the goal that far inside.
        goal_half_m = max(half_m - spec.settle_depth_m, 0.0)
        for _ in range(_MAX_RECOVERY_ATTEMPTS):
            start_m = target_depth_m + goal_half_m * (2.0 * uniform(rng_state) - 1.0)
            if _recover(env, start_m, spec, rng_state):
                break
        env[E_CENTER] = env[E_REC_AVG] + spec.start_trim_error_deg
        if lspec.neutral_gain > 0.0:
            if env[E_NEUTRAL] == 0.0:
                env[E_NEUTRAL] = env[E_CENTER]
            env[E_CENTER] = env[E_NEUTRAL]
        env[E_CMD] = env[E_CENTER]
    else:
        # The paper's simulation: restart at rest at a random depth, gear at neutral.
        start_m = target_depth_m + half_m * (2.0 * uniform(rng_state) - 1.0)
        env[E_CENTER] = neutral_alpha_kernel(spec) + spec.start_trim_error_deg
        env[E_CMD] = env[E_CENTER]
        plant_place(env[:E_PLANT_END], start_m, 0.0, env[E_CENTER])
        env[E_OBS_X1] = start_m
        env[E_OBS_X2] = 0.0
        measure_kernel(env, 0.0, spec, rng_state)
    env[E_STARTED] = 1.0
    if lspec.velocity_diff_steps > 0:
        # The agent has been measuring depth all along (recovery, or at rest): a full, flat history.
        env[E_RING:E_RING + MAX_VELOCITY_DIFF_STEPS] = env[E_DEPTH_MEAS]
        env[E_RING_POS] = 0.0
        env[E_VEL_EST] = 0.0
    if lspec.filter_depth_gain > 0.0:
        # Handed over at rest at the measured depth; the bias learnt so far carries over (the same gear).
        env[E_FILT_Z] = env[E_DEPTH_MEAS]
        env[E_FILT_V] = 0.0
        env[E_VEL_EST] = 0.0
    return _state(env, target_depth_m, spec, lspec)


@njit(cache=True, error_model="numpy", inline="always")
def _depth_difference(env: NDArray[np.float64], spec: KernelSpec, lspec: KernelSpec) -> None:
    """The learner's velocity as (z_t - z_{t-k}) / (k dt) over its own measured depths."""
    k = lspec.velocity_diff_steps
    pos = int(env[E_RING_POS])
    oldest = env[E_RING + (pos + MAX_VELOCITY_DIFF_STEPS - k) % MAX_VELOCITY_DIFF_STEPS]
    env[E_RING + pos] = env[E_DEPTH_MEAS]
    env[E_RING_POS] = float((pos + 1) % MAX_VELOCITY_DIFF_STEPS)
    env[E_VEL_EST] = (env[E_DEPTH_MEAS] - oldest) / (k * spec.control_period_s)


@njit(cache=True, error_model="numpy", inline="always")
def _velocity_filter(env: NDArray[np.float64], spec: KernelSpec, lspec: KernelSpec) -> None:
    """The learner's velocity from its depth filter (LearnerConfig.filter_depth_gain): predict one control
    period with the commanded gear angle's acceleration, then correct with the measured depth."""
    dt = spec.control_period_s
    v = env[E_FILT_V]
    acc = (lspec.filter_accel_per_deg * (env[E_CMD] - env[E_CENTER]) - lspec.filter_drag_per_m * v * abs(v)
           + env[E_FILT_B])
    z = env[E_FILT_Z] + dt * v + 0.5 * dt * dt * acc
    v += dt * acc
    r = env[E_DEPTH_MEAS] - z
    env[E_FILT_Z] = z + lspec.filter_depth_gain * r
    env[E_FILT_V] = v + lspec.filter_velocity_gain * r / dt
    env[E_FILT_B] += lspec.filter_bias_gain * r / (dt * dt)
    env[E_VEL_EST] = env[E_FILT_V]


@njit(cache=True, error_model="numpy", inline="always")
def learner_depth(env: NDArray[np.float64], lspec: KernelSpec) -> float:
    """The depth the learner sees: its filter's estimate (LearnerConfig.filter_depth_state) or the reading."""
    return env[E_FILT_Z] if lspec.filter_depth_state else env[E_DEPTH_MEAS]


@njit(cache=True, error_model="numpy", inline="always")
def episode_cell_kernel(
    env: NDArray[np.float64], target_depth_m: float, spec: KernelSpec, lspec: KernelSpec
) -> int:
    """The unclipped grid cell of the current measurement (the shared model's successor, inside or out)."""
    fraction = (env[E_CMD] - env[E_CENTER]) / spec.action_window_deg
    return raw_cell_kernel(learner_depth(env, lspec), env[E_VEL_EST], target_depth_m, fraction, lspec)


@njit(cache=True, error_model="numpy", inline="always")
def episode_steps(spec: KernelSpec) -> int:
    """Learner steps in a successful episode (3000 = 300 s at 0.1 s)."""
    return int(np.round(spec.episode_limit_s / spec.control_period_s))


@njit(cache=True, error_model="numpy", inline="always")
def _state(env: NDArray[np.float64], target_depth_m: float, spec: KernelSpec, lspec: KernelSpec) -> int:
    fraction = (env[E_CMD] - env[E_CENTER]) / spec.action_window_deg
    return state_index_kernel(learner_depth(env, lspec), env[E_VEL_EST], target_depth_m, fraction, lspec)


episode_state_kernel = _state  # the learner's state of the current measurement (gym/task.py: a placed start)


# Inlined into the study's trial loop (its hottest call, once per learner step): 1.2x on the whole study.
@njit(cache=True, error_model="numpy", inline="always")
def episode_step_kernel(
    env: NDArray[np.float64],
    action: int,
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    rng_state: NDArray[np.uint64],
) -> tuple[int, float, bool, bool]:
    """Apply action (0 = less volume, 1 = more) for one control period: (state, reward, term, trunc)."""
    # Issue 43's screened options only (off in every preset): no extra work per step without them.
    screened = lspec.hold_depth_m > 0.0 or lspec.neutral_gain > 0.0
    error_m = learner_depth(env, lspec) - target_depth_m if screened else 0.0
    held = lspec.hold_depth_m > 0.0 and abs(error_m) < lspec.hold_depth_m and abs(env[E_VEL_EST]) < lspec.hold_speed_mps
    base = env[E_CMD]
    if held:
        size = 0.0
        if lspec.neutral_gain > 0.0 and env[E_HELD] == 0.0:
            # Entering a hold with a neutral found: go to it (held anywhere else the gear would push the robot out
            # of the hold), overshooting by hold_lash_deg in the direction of the move so the output lands on it.
            up = env[E_NEUTRAL] > base or (env[E_NEUTRAL] == base and env[E_LAST_ACTION] == 1.0)
            base = env[E_NEUTRAL] + (lspec.hold_lash_deg if up else -lspec.hold_lash_deg)
    else:
        size = step_size_kernel(env[E_VEL_EST], spec.action_step_deg, action != env[E_LAST_ACTION], lspec)
        env[E_LAST_ACTION] = action
    env[E_HELD] = 1.0 if held else 0.0
    step = size if action == 1 else -size
    low = env[E_CENTER] - spec.action_window_deg
    high = env[E_CENTER] + spec.action_window_deg
    env[E_CMD] = min(max(base + step, low), high)
    # The learner believes every step lasts control_period_s; the plant may run a jittered one.
    plant_step(env[:E_PLANT_END], env[E_CMD], jittered_period_s(spec.control_period_s, spec, rng_state), spec)
    env[E_STEPS] += 1.0
    # The neutral the learner finds: its command's average while near the target (a chatter about the neutral).
    if lspec.neutral_gain > 0.0 and not held and abs(error_m) < 0.25 * lspec.z_tol_m \
            and abs(env[E_VEL_EST]) < 0.25 * lspec.zdot_tol_mps:
        env[E_NEUTRAL] += lspec.neutral_gain * (env[E_CMD] - env[E_NEUTRAL])
    measure_kernel(env, spec.control_period_s, spec, rng_state)
    if lspec.velocity_diff_steps > 0:
        _depth_difference(env, spec, lspec)
    elif lspec.filter_depth_gain > 0.0:
        _velocity_filter(env, spec, lspec)
    next_state = _state(env, target_depth_m, spec, lspec)
    reward = reward_kernel(learner_depth(env, lspec), target_depth_m, next_state, lspec)
    terminal = lspec.z_cells * lspec.zdot_cells * lspec.actuator_bins
    terminated = next_state == terminal
    # Reaching the time limit is a success and a truncation, not a terminal state (no -10).
    truncated = (not terminated) and env[E_STEPS] >= episode_steps(spec)
    return next_state, reward, terminated, truncated

