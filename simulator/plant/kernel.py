"""Compiled equations of motion (diving-agent.md s. 2): semi-implicit Euler with the command held, sub-step by
sub-step (the reference) or its sum over a control period in closed form (spec.closed_form_step, issue 43)."""

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


# The closed form is used only this far from the surface and the floor, where no sub-step can meet them (at 0.5 m/s, a
# velocity the agent never reaches, a 0.1 s period moves it 5 cm); nearer, the sub-steps run.
_CLOSED_FORM_MARGIN_M = 0.1
_DRAG_PASSES = 1  # passes of the drag along the period's velocity (a second moves depth by under 1e-3 mm in 300 s)
# Reciprocals written once: a division costs several multiplications and LLVM keeps `/ 6.0` a division.
_HALF, _SIXTH, _TWELFTH, _THIRTIETH = 0.5, 1.0 / 6.0, 1.0 / 12.0, 1.0 / 30.0


@njit(cache=True, error_model="numpy", inline="always")
def _ramp_sums(alpha0: float, target: float, max_move: float, n: int) -> tuple[float, float]:
    """(sum_k alpha_k, sum_k (n - k + 1) alpha_k), k = 1..n, of the ideal stepper's angle after each sub-step: it
    moves max_move toward target per sub-step (the reference's `alpha += clip(target - alpha)`), then stays."""
    d = target - alpha0
    span = abs(d)
    sign = 1.0 if d >= 0.0 else -1.0
    # Full moves before the last, partial one (a float's rounding of the quotient only moves a sub-step whose
    # move is the remainder itself).
    j = min(int(span / max_move), n) if max_move > 0.0 else 0
    jj = float(j * (j + 1))
    full1 = max_move * jj * _HALF
    full2 = max_move * jj * ((n + 1) * _HALF - (2 * j + 1) * _SIXTH)
    rest = float(n - j)
    s1 = n * alpha0 + sign * (full1 + rest * span)
    s2 = n * (n + 1) * _HALF * alpha0 + sign * (full2 + span * rest * (rest + 1.0) * _HALF)
    return s1, s2


@njit(cache=True, error_model="numpy", inline="always")
def _closed_form_hull(state: NDArray[np.float64], s1: float, s2: float, n: int, h: float,
                      spec: KernelSpec) -> tuple[float, float]:
    """Depth and velocity after n sub-steps of _hull, given the sums of the gear angle over them (_ramp_sums).

    With v_k = v_{k-1} + h a_k and z_k = z_{k-1} + h v_k: v_n = v_0 + h sum a_k and
    z_n = z_0 + n h v_0 + h^2 sum (n - k + 1) a_k, exact for the angle's part. The drag depends on v_{k-1}: it is
    expanded to second order about the period's start, along a velocity profile whose sum is exact for the angle's
    ramps (its share of z'' is small near a hover, and it changes little in one period). The hull's compressibility
    is taken along a straight line of depth (the caller keeps the sub-steps for a compressible hull)."""
    a0, a_alpha, a_z, a_drag = force_coefficients(spec)
    z0, v0 = state[Z], state[ZDOT]
    n_f = float(n)
    w1 = n_f  # sum_k 1
    m = n_f - 1.0
    w2 = n_f * (n_f + 1.0) * _HALF  # sum_k (n - k + 1)
    # Power sums over i = k - 1 = 0..n-1: sum i .. sum i^5, and (n - i)-weighted ones for the depth.
    l1 = n_f * m * _HALF
    p2 = m * n_f * (2.0 * m + 1.0) * _SIXTH
    p3 = l1 * l1
    p4 = p2 * (3.0 * m * m + 3.0 * m - 1.0) * (6.0 * _THIRTIETH)
    p5 = p3 * (2.0 * m * m + 2.0 * m - 1.0) * (4.0 * _TWELFTH)
    l2 = n_f * l1 - p2
    base1 = a0 * w1 + a_alpha * s1 + a_z * (z0 * w1 + h * v0 * l1)
    base2 = a0 * w2 + a_alpha * s2 + a_z * (z0 * w2 + h * v0 * l2)
    # Drag g(v) = a_drag v|v| about the start: g0 + g1 (v - v0) + g2 (v - v0)^2 (exact while v keeps its sign).
    g0 = a_drag * v0 * abs(v0)
    g1 = 2.0 * a_drag * abs(v0)
    g2 = a_drag if v0 >= 0.0 else -a_drag
    # Without the drag's change, v_{k-1} - v0 = u_{k-1} = h sum_{j<k} e_j, e_j = a_j - g0 (the angle's ramp exactly):
    # sum_k u_{k-1} = h sum_j (n - j) e_j. The drag's change feeds back at first order as -g1 h sum_{j<k} u_{j-1},
    # summed with a constant e (its variation is a further factor g1 h n ~ 0.01 smaller).
    e1 = base1 - g0 * w1
    e2 = base2 - g0 * w2
    u_sum = h * (e2 - e1)
    u_sum -= g1 * h * h * e1 * m * (m - 1.0) * _SIXTH
    inv_det = 1.0 / (n_f * p2 - n_f * n_f * l1)
    v_end = v0 + h * e1
    for _ in range(_DRAG_PASSES):
        # v_{k-1} - v0 as a quadratic A i + B i^2 through the period's end and with the sum found above: the
        # angle's ramps bend the velocity, which a straight line would miss in the quadratic part of the drag.
        du = v_end - v0
        a_lin = (du * p2 - n_f * n_f * u_sum) * inv_det
        b_quad = (n_f * u_sum - l1 * du) * inv_det
        if v0 * v_end > 0.0:
            sq1 = a_lin * a_lin * p2 + 2.0 * a_lin * b_quad * p3 + b_quad * b_quad * p4
            w_lin = a_lin * l2 + b_quad * (n_f * p2 - p3)
            w_sq = (a_lin * a_lin * (n_f * p2 - p3) + 2.0 * a_lin * b_quad * (n_f * p3 - p4)
                    + b_quad * b_quad * (n_f * p4 - p5))
            drag1 = g0 * w1 + g1 * u_sum + g2 * sq1
            drag2 = g0 * w2 + g1 * w_lin + g2 * w_sq
        else:
            # A reversal inside the period (the drag is then at its smallest): term by term along the quadratic.
            drag1 = 0.0
            drag2 = 0.0
            for k in range(1, n + 1):
                i = k - 1.0
                v = v0 + a_lin * i + b_quad * i * i
                g = a_drag * v * abs(v)
                drag1 += g
                drag2 += (n - k + 1) * g
        v_end = v0 + h * (base1 - drag1)
    z_end = z0 + n_f * h * v0 + h * h * (base2 - drag2)
    return z_end, v_end


@njit(cache=True, error_model="numpy", inline="always")
def _closed_form_step(state: NDArray[np.float64], target_deg: float, dt_s: float, n_sub: int, h: float,
                      spec: KernelSpec) -> bool:
    """plant_step's sub-steps summed in closed form (issue 43: a study's plant at O(1) per period instead of n_sub
    sub-steps). False, with the state untouched, near the surface or the floor, where the sub-steps must run.

    The gear's angle after each sub-step is summed exactly (a ramp for the ideal stepper; the gear train of _gear
    stepped for backlash or a dead band, a cheap chain), the hull in _closed_form_hull, the port's lag along a
    straight line of depth over the period (exact discretisation of the lag per sub-step)."""
    z0 = state[Z]
    # A compressible hull is unstable: any difference grows without bound, so it keeps the sub-steps.
    if (z0 < _CLOSED_FORM_MARGIN_M or z0 > spec.floor_depth_m - _CLOSED_FORM_MARGIN_M
            or spec.compressibility_m3pm != 0.0 or n_sub < 2):
        return False
    max_move_deg = spec.alpha_rate_dps * h
    real_gear = spec.backlash_deg > 0.0 or spec.dead_band_deg > 0.0
    alpha = state[ALPHA]
    motor = state[MOTOR]
    if real_gear:
        half_dead, half_lash = 0.5 * spec.dead_band_deg, 0.5 * spec.backlash_deg
        s1 = 0.0
        s2 = 0.0
        for k in range(1, n_sub + 1):
            motor, alpha = _gear(motor, alpha, target_deg, max_move_deg, half_dead, half_lash)
            s1 += alpha
            s2 += (n_sub - k + 1) * alpha
    else:
        s1, s2 = _ramp_sums(alpha, target_deg, max_move_deg, n_sub)
        alpha += min(max(target_deg - alpha, -max_move_deg * n_sub), max_move_deg * n_sub)
        motor = alpha
    z_end, v_end = _closed_form_hull(state, s1, s2, n_sub, h, spec)
    if z_end < _CLOSED_FORM_MARGIN_M or z_end > spec.floor_depth_m - _CLOSED_FORM_MARGIN_M:
        return False
    if spec.pressure_lag_s > 0.0:
        # The reference's sensed += (1 - r)(z_k - sensed) per sub-step, z_k = z0 + k dz, summed:
        # r^n sensed + (1 - r^n) z0 + dz [n - (n + 1) r + r^(n+1)] / (1 - r).
        r = np.exp(-h / spec.pressure_lag_s)
        r_n = np.exp(-n_sub * h / spec.pressure_lag_s)
        dz = (z_end - z0) / n_sub
        state[SENSED_Z] = (r_n * state[SENSED_Z] + (1.0 - r_n) * z0
                           + dz * (n_sub - (n_sub + 1) * r + r_n * r) / (1.0 - r))
    else:
        state[SENSED_Z] = z_end
    state[Z] = z_end
    state[ZDOT] = v_end
    state[ALPHA] = alpha
    state[MOTOR] = motor
    state[CLOCK_S] += dt_s
    return True


@njit(cache=True, error_model="numpy", inline="always")
def plant_step(state: NDArray[np.float64], alpha_cmd_deg: float, dt_s: float, spec: KernelSpec) -> None:
    """Advance the plant by dt_s in fixed sub-steps of at most spec.substep_s, command held.

    The ideal actuator (no backlash, no dead band) and sensor port (no lag) run here; the rest in
    _real_plant_step; with spec.closed_form_step, their sum in closed form (_closed_form_step) where it applies."""
    n_sub = max(1, int(np.ceil(dt_s / spec.substep_s - 1e-9)))
    h = dt_s / n_sub
    target_deg = min(max(alpha_cmd_deg, 0.0), spec.alpha_max_deg)
    if spec.closed_form_step and _closed_form_step(state, target_deg, dt_s, n_sub, h, spec):
        return
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
