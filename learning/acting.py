"""Compiled per-step pieces of the learner: state index, reward, exploration and action choice."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.rng import uniform
from learning.spec import KernelSpec

TIED = 2  # policy entry of a tied state when ties are drawn at every step (LearnerConfig.ties_per_step)


@njit(cache=True, error_model="numpy", inline="always")
def _cell(x: float, half_width: float, cells: int) -> int:
    i = int(np.floor((x + half_width) / (2.0 * half_width) * cells))
    return min(max(i, 0), cells - 1)


@njit(cache=True, error_model="numpy", inline="always")
def state_index_kernel(
    depth_m: float, velocity_mps: float, target_depth_m: float, actuator_fraction: float, spec: KernelSpec
) -> int:
    """Grid cell of (depth error, velocity[, actuator bin]); the terminal state S-1 outside the region."""
    terminal = spec.z_cells * spec.zdot_cells * spec.actuator_bins
    error_m = depth_m - target_depth_m
    if abs(error_m) >= spec.z_tol_m:
        return terminal
    if not spec.depth_only_terminal and abs(velocity_mps) >= spec.zdot_tol_mps:
        return terminal
    iz = _cell(error_m, spec.z_tol_m, spec.z_cells)
    # With the depth-only terminal the outer velocity cells are open-ended (clipped), as in the firmware.
    iv = _cell(velocity_mps, spec.zdot_tol_mps, spec.zdot_cells)
    ib = _cell(actuator_fraction, 1.0, spec.actuator_bins) if spec.actuator_bins > 1 else 0
    return (ib * spec.z_cells + iz) * spec.zdot_cells + iv


@njit(cache=True, error_model="numpy", inline="always")
def reward_kernel(depth_m: float, target_depth_m: float, next_state: int, spec: KernelSpec) -> float:
    """The paper's reward (eq. 2): -|z - z_d| per step, the terminal reward on leaving the region."""
    if next_state == spec.z_cells * spec.zdot_cells * spec.actuator_bins:
        return spec.terminal_reward
    return -abs(depth_m - target_depth_m)


@njit(cache=True, error_model="numpy", inline="always")
def step_size_kernel(velocity_mps: float, plant_step_deg: float, reversal: bool, spec: KernelSpec) -> float:
    """The gear step of an action: fine_step_deg while the velocity the learner sees is under fine_speed_mps (near
    a hover, LearnerConfig.fine_step_deg), there fine_reversal_deg instead if set and the action reverses the last
    one (or is the episode's first), else the plant's step. firmware/src/learner.c learner_step_deg is its C twin."""
    if spec.fine_step_deg > 0.0 and abs(velocity_mps) < spec.fine_speed_mps:
        if reversal and spec.fine_reversal_deg > 0.0:
            return spec.fine_reversal_deg
        return spec.fine_step_deg
    return plant_step_deg


@njit(cache=True, error_model="numpy", inline="always")
def explore_probability(episode: int, spec: KernelSpec) -> float:
    """Linear decay from p_explore_start at episode 0 to p_explore_end at explore_decay_episodes."""
    frac = min(episode / spec.explore_decay_episodes, 1.0)
    return spec.p_explore_start + (spec.p_explore_end - spec.p_explore_start) * frac


@njit(cache=True, error_model="numpy", inline="always")
def select_action_kernel(
    policy: NDArray[np.int8], state: int, p_explore: float, spec: KernelSpec, rng_state: NDArray[np.uint64]
) -> int:
    """The greedy action of the current policy, flipped with probability p_explore (Alg. 2, fixed)."""
    action = int(policy[state])
    if action == TIED:
        action = 1 if uniform(rng_state) < 0.5 else 0
    p_rand = uniform(rng_state)
    explore = p_rand > p_explore if spec.explore_literal_gt else p_rand < p_explore
    if explore:
        action = 1 - action
    return action
