"""Compiled equations of motion (diving-agent.md s. 2): semi-implicit Euler with the command held."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.rng import uniform
from learning.spec import KernelSpec

# Layout of the plant state array.
Z = 0  # depth, m, positive down
ZDOT = 1  # velocity, m/s, positive down
ALPHA = 2  # gear output angle, deg
MOTOR = 3  # stepper side of the gear train, deg (differs from ALPHA by at most half the backlash)
SENSED_Z = 4  # depth the pressure port sees (lags Z by pressure_lag_s), m
CLOCK_S = 5  # plant time since the start, s (the sensor's drift and coloured noise run on it)
NOISE_PA = 6  # the sensor's AR(1) noise state, Pa
LAST_READ_S = 7  # plant time of the last reading, s
PLANT_SIZE = 8


@njit(cache=True, error_model="numpy", inline="always")
def force_coefficients(spec: KernelSpec) -> tuple[float, float, float, float]:
    """(a0, a_alpha, a_z, a_drag) with z'' = a0 + a_alpha alpha + a_z z - a_drag z'|z'|.

    From (m + m_a) z'' = m g - rho g (V0 + V_adj(alpha) - chi z) - k z'|z'|, z down, where
    V_adj = dV (alpha / alpha_max - 1/2) and a compressible hull (chi > 0) loses volume with depth,
    which makes the hover point unstable.
    """
    inertia_kg = spec.mass_kg + spec.added_mass_kg
    rho_g = spec.water_density_kgpm3 * spec.gravity_mps2
    fixed_volume_m3 = spec.mass_kg / spec.water_density_kgpm3 * (1.0 + spec.trim_error_fraction)
    net_weight_n = spec.mass_kg * spec.gravity_mps2 - rho_g * (fixed_volume_m3 - 0.5 * spec.stroke_volume_m3)
    a0 = net_weight_n / inertia_kg
    a_alpha = -rho_g * spec.stroke_volume_m3 / spec.alpha_max_deg / inertia_kg
    a_z = rho_g * spec.compressibility_m3pm / inertia_kg
    a_drag = spec.drag_kgpm / inertia_kg
    return a0, a_alpha, a_z, a_drag


@njit(cache=True, error_model="numpy")
def acceleration_mps2(depth_m: float, velocity_mps: float, alpha_deg: float, spec: KernelSpec) -> float:
    """z'' at the given depth, velocity and gear angle (see force_coefficients)."""
    a0, a_alpha, a_z, a_drag = force_coefficients(spec)
    return a0 + a_alpha * alpha_deg + a_z * depth_m - a_drag * velocity_mps * abs(velocity_mps)


@njit(cache=True, error_model="numpy")
def plant_place(state: NDArray[np.float64], depth_m: float, velocity_mps: float, alpha_deg: float) -> None:
    """Put the agent somewhere at once (a restart): gear train closed, the sensor's port at the new depth."""
    state[Z] = depth_m
    state[ZDOT] = velocity_mps
    state[ALPHA] = alpha_deg
    state[MOTOR] = alpha_deg
    state[SENSED_Z] = depth_m


@njit(cache=True, error_model="numpy", inline="always")
def jittered_period_s(period_s: float, spec: KernelSpec, rng_state: NDArray[np.uint64]) -> float:
    """How long a control step of nominal period_s really lasts (draws only when control_jitter_s > 0)."""
    if spec.control_jitter_s > 0.0:
        return period_s + spec.control_jitter_s * (2.0 * uniform(rng_state) - 1.0)
    return period_s


@njit(cache=True, error_model="numpy", inline="always")
def _gear(motor: float, alpha: float, target: float, max_move: float, half_dead: float,
          half_lash: float) -> tuple[float, float]:
    """One sub-step of the real gear train: (motor, output angle)."""
    error = target - motor
    if abs(error) > half_dead:
        motor += min(max(error, -max_move), max_move)
    # The output stays put until the motor has taken up the lost motion on its side.
    return motor, min(max(alpha, motor - half_lash), motor + half_lash)


@njit(cache=True, error_model="numpy", inline="always")
def _hull(z: float, zdot: float, alpha: float, h: float, h_a0: float, h_alpha: float, h_z: float, h_drag: float,
          compressible: bool, floor_m: float) -> tuple[float, float]:
    """One sub-step of the hull: (depth, velocity)."""
    # Semi-implicit Euler: the new velocity moves the hull.
    push = h_a0 + h_alpha * alpha
    if compressible:
        push += h_z * z
    zdot = (zdot + push) - (h_drag * zdot) * abs(zdot)
    z += h * zdot
    # Free surface and floor: the hull cannot leave the water column.
    if z < 0.0:
        z = 0.0
        zdot = max(zdot, 0.0)
    elif z > floor_m:
        z = floor_m
        zdot = min(zdot, 0.0)
    return z, zdot


@njit(cache=True, error_model="numpy")
def _real_plant_step(state: NDArray[np.float64], target_deg: float, dt_s: float, n_sub: int, h: float,
                     spec: KernelSpec) -> None:
    """plant_step with backlash, dead band or a lagging port: the gear train of _gear and the port's
    first-order lag per sub-step. Not inlined: its branches in the ideal plant's inlined loop cost a
    study ~25 % of its CPU."""
    max_move_deg = spec.alpha_rate_dps * h
    a0, a_alpha, a_z, a_drag = force_coefficients(spec)
    h_a0, h_alpha, h_z, h_drag = h * a0, h * a_alpha, h * a_z, h * a_drag
    compressible = a_z != 0.0
    z, zdot, alpha = state[Z], state[ZDOT], state[ALPHA]
    real_gear = spec.backlash_deg > 0.0 or spec.dead_band_deg > 0.0
    lagged = spec.pressure_lag_s > 0.0
    motor = state[MOTOR] if real_gear else alpha
    sensed = state[SENSED_Z]
    half_dead, half_lash = 0.5 * spec.dead_band_deg, 0.5 * spec.backlash_deg
    # Exact discretisation of the port's first-order lag over one sub-step.
    lag_gain = 1.0 - np.exp(-h / spec.pressure_lag_s) if lagged else 1.0
    for _ in range(n_sub):
        if real_gear:
            motor, alpha = _gear(motor, alpha, target_deg, max_move_deg, half_dead, half_lash)
        else:
            alpha += min(max(target_deg - alpha, -max_move_deg), max_move_deg)
        z, zdot = _hull(z, zdot, alpha, h, h_a0, h_alpha, h_z, h_drag, compressible, spec.floor_depth_m)
        if lagged:
            sensed += lag_gain * (z - sensed)
    state[Z] = z
    state[ZDOT] = zdot
    state[ALPHA] = alpha
    state[MOTOR] = motor if real_gear else alpha
    state[SENSED_Z] = sensed if lagged else z
    state[CLOCK_S] += dt_s


@njit(cache=True, error_model="numpy", inline="always")
def plant_step(state: NDArray[np.float64], alpha_cmd_deg: float, dt_s: float, spec: KernelSpec) -> None:
    """Advance the plant by dt_s in fixed sub-steps of at most spec.substep_s, command held.

    The ideal actuator (no backlash, no dead band) and sensor port (no lag) run here; the rest in
    _real_plant_step."""
    n_sub = max(1, int(np.ceil(dt_s / spec.substep_s - 1e-9)))
    h = dt_s / n_sub
    target_deg = min(max(alpha_cmd_deg, 0.0), spec.alpha_max_deg)
    if spec.backlash_deg > 0.0 or spec.dead_band_deg > 0.0 or spec.pressure_lag_s > 0.0:
        _real_plant_step(state, target_deg, dt_s, n_sub, h, spec)
        return
    max_move_deg = spec.alpha_rate_dps * h
    a0, a_alpha, a_z, a_drag = force_coefficients(spec)
    # Coefficients scaled by h, and the drag written as (h k zdot)|zdot|, keep the velocity's own
    # dependency chain short: the sub-step loop is latency-bound and runs ~10^9 times in a study.
    h_a0, h_alpha, h_z, h_drag = h * a0, h * a_alpha, h * a_z, h * a_drag
    compressible = a_z != 0.0
    z = state[Z]
    zdot = state[ZDOT]
    alpha = state[ALPHA]
    floor_m = spec.floor_depth_m
    for _ in range(n_sub):
        # The stepper moves toward the command at its top rate and stops at the end stops.
        alpha += min(max(target_deg - alpha, -max_move_deg), max_move_deg)
        z, zdot = _hull(z, zdot, alpha, h, h_a0, h_alpha, h_z, h_drag, compressible, floor_m)
    state[Z] = z
    state[ZDOT] = zdot
    state[ALPHA] = alpha
    state[MOTOR] = alpha
    state[SENSED_Z] = z
    state[CLOCK_S] += dt_s
