"""Compiled equations of motion (diving-agent.md s. 2): semi-implicit Euler with the command held."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

# Layout of the plant state array.
Z = 0  # depth, m, positive down
ZDOT = 1  # velocity, m/s, positive down
ALPHA = 2  # gear output angle, deg
PLANT_SIZE = 3


@njit(cache=True)
def acceleration_mps2(depth_m: float, velocity_mps: float, alpha_deg: float, spec: tuple) -> float:
    """(m + m_a) z'' = (m - rho V0) g - rho g (V_adj + chi z... ) - k z'|z'|, z down."""
    rho_g = spec.water_density_kgpm3 * spec.gravity_mps2
    fixed_volume_m3 = spec.mass_kg / spec.water_density_kgpm3 * (1.0 + spec.trim_error_fraction)
    adjustable_m3 = spec.stroke_volume_m3 * (alpha_deg / spec.alpha_max_deg - 0.5)
    # A compressible hull loses volume with depth, which makes the hover point unstable.
    volume_m3 = fixed_volume_m3 + adjustable_m3 - spec.compressibility_m3pm * depth_m
    force_n = spec.mass_kg * spec.gravity_mps2 - rho_g * volume_m3
    force_n -= spec.drag_kgpm * velocity_mps * abs(velocity_mps)
    return force_n / (spec.mass_kg + spec.added_mass_kg)


@njit(cache=True)
def plant_step(state: NDArray[np.float64], alpha_cmd_deg: float, dt_s: float, spec: tuple) -> None:
    """Advance the plant by dt_s in fixed sub-steps of at most spec.substep_s, command held."""
    n_sub = max(1, int(np.ceil(dt_s / spec.substep_s - 1e-9)))
    h = dt_s / n_sub
    max_move_deg = spec.alpha_rate_dps * h
    target_deg = min(max(alpha_cmd_deg, 0.0), spec.alpha_max_deg)
    for _ in range(n_sub):
        # The stepper moves toward the command at its top rate and stops at the end stops.
        move = min(max(target_deg - state[ALPHA], -max_move_deg), max_move_deg)
        state[ALPHA] += move
        state[ZDOT] += h * acceleration_mps2(state[Z], state[ZDOT], state[ALPHA], spec)
        state[Z] += h * state[ZDOT]
        # Free surface and floor: the hull cannot leave the water column.
        if state[Z] < 0.0:
            state[Z] = 0.0
            state[ZDOT] = max(state[ZDOT], 0.0)
        elif state[Z] > spec.floor_depth_m:
            state[Z] = spec.floor_depth_m
            state[ZDOT] = min(state[ZDOT], 0.0)
