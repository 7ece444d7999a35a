"""The boundary-layer sliding mode velocity observer of the firmware (diving-agent.md s. 3)."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.config import LearnerConfig
from learning.spec import KernelSpec, direct_entry
from simulator.parameters import PlantParams, kernel_params

X1 = 0  # depth estimate, m
X2 = 1  # velocity estimate, m/s
OBSERVER_SIZE = 2


@njit(cache=True, error_model="numpy", inline="always")
def _sat(x: float) -> float:
    return min(max(x, -1.0), 1.0)


@njit(cache=True, error_model="numpy", inline="always")
def observer_update_kernel(
    state: NDArray[np.float64], measured_depth_m: float, dt_s: float, spec: KernelSpec
) -> float:
    """One observer step on the measured depth; returns the velocity estimate."""
    rho = spec.observer_rho_mps
    phi = spec.observer_phi_m
    state[X1] = state[X1] - dt_s * rho * _sat((state[X1] - measured_depth_m) / phi)
    state[X2] = state[X2] + dt_s / spec.observer_tau_s * (
        -state[X2] - rho * _sat((state[X1] - measured_depth_m) / phi)
    )
    return state[X2]


class SlidingModeObserver:
    """Estimates the velocity from depth readings with about 0.4 s of lag inside its boundary layer."""

    def __init__(self, params: PlantParams) -> None:
        self._spec = kernel_params(params)
        self._state = np.zeros(OBSERVER_SIZE)
        self._update = direct_entry(observer_update_kernel, self._state, 0.0, 0.0, self._spec)

    @property
    def state(self) -> NDArray[np.float64]:
        """The live estimate (X1, X2), for compiled steps that chain the kernels."""
        return self._state

    def reset(self, depth_m: float) -> None:
        """Start at depth_m and rest."""
        self._state[X1] = depth_m
        self._state[X2] = 0.0

    def update(self, measured_depth_m: float, dt_s: float) -> float:
        """Feed one depth reading taken dt_s after the previous one; returns the velocity in m/s."""
        return float(self._update(self._state, measured_depth_m, dt_s, self._spec))


class DepthDifference:
    """The learner's own velocity input: (z_t - z_{t-k}) / (k dt) over its measured depths.

    The agent's alternative to the observer (no lag model, k-1 steps of averaging); the study's kernel
    keeps the same ring in its environment array (simulator/plant/episode.py).
    """

    def __init__(self, steps: int) -> None:
        self._steps = steps
        self._ring = [0.0] * steps
        self._pos = 0

    def reset(self, depth_m: float) -> None:
        """A flat history at the current depth (the agent was measuring all along)."""
        self._ring = [depth_m] * self._steps
        self._pos = 0

    def update(self, depth_m: float, dt_s: float) -> float:
        """Push the newest depth; the velocity over the last k control periods."""
        oldest = self._ring[self._pos]
        self._ring[self._pos] = depth_m
        self._pos = (self._pos + 1) % self._steps
        return (depth_m - oldest) / (self._steps * dt_s)


class VelocityFilter:
    """The learner's velocity filter (LearnerConfig.filter_*): the agent's twin of the study kernel's
    (simulator/plant/episode.py _velocity_filter, which keeps the same three numbers in its environment array)."""

    def __init__(self, config: LearnerConfig) -> None:
        self._c = config
        self.depth_m = self.velocity_mps = self.bias_mps2 = 0.0

    def reset(self, depth_m: float, velocity_mps: float = 0.0) -> None:
        """An episode starts here; the acceleration bias learnt so far is kept (the same gear)."""
        self.depth_m, self.velocity_mps = depth_m, velocity_mps

    def update(self, depth_m: float, cmd_offset_deg: float, dt_s: float) -> float:
        """One period of dt_s with the command cmd_offset_deg from the window's centre, then the reading depth_m."""
        c, v = self._c, self.velocity_mps
        acc = c.filter_accel_per_deg * cmd_offset_deg - c.filter_drag_per_m * v * abs(v) + self.bias_mps2
        z = self.depth_m + dt_s * v + 0.5 * dt_s * dt_s * acc
        v += dt_s * acc
        r = depth_m - z
        self.depth_m = z + c.filter_depth_gain * r
        self.velocity_mps = v + c.filter_velocity_gain * r / dt_s
        self.bias_mps2 += c.filter_bias_gain * r / (dt_s * dt_s)
        return self.velocity_mps
