"""The sliding mode recovery controller that brings the agent back to a start depth between episodes."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.spec import KernelSpec, direct_entry
from simulator.parameters import PlantParams, kernel_params

AVG = 0  # learned neutral angle alpha_avg, deg
CALM_S = 1  # how long |e| and |z'| have been inside the settle band, s
ELAPSED_S = 2  # time since this recovery began, s
RECOVERY_SIZE = 3

# The running mean of alpha is taken while the agent is nearly still: alpha is then close to neutral
# wherever it hovers, even at the proportional offset a trim error leaves before the mean has converged.
_AVERAGING_BAND_FACTOR = 2.0


@njit(cache=True, error_model="numpy")
def recovery_init(state: NDArray[np.float64], alpha_avg_deg: float) -> None:
    """Begin a recovery, keeping the neutral angle learned so far."""
    state[AVG] = alpha_avg_deg
    state[CALM_S] = 0.0
    state[ELAPSED_S] = 0.0


@njit(cache=True, error_model="numpy")
def recovery_update_kernel(
    state: NDArray[np.float64],
    depth_m: float,
    velocity_mps: float,
    alpha_deg: float,
    target_depth_m: float,
    dt_s: float,
    spec: KernelSpec,
) -> float:
    """One controller period; returns alpha_cmd_deg. Deeper than the target (s > 0) means more volume."""
    error_m = depth_m - target_depth_m
    surface = velocity_mps + spec.recovery_lambda_per_s * error_m
    sat = min(max(surface / spec.recovery_phi_mps, -1.0), 1.0)
    if abs(velocity_mps) < _AVERAGING_BAND_FACTOR * spec.settle_velocity_mps:
        # Integral action: alpha at a hover is the neutral angle, so its running mean converges there.
        state[AVG] += dt_s / spec.recovery_avg_time_s * (alpha_deg - state[AVG])
    calm = abs(error_m) < spec.settle_depth_m and abs(velocity_mps) < spec.settle_velocity_mps
    state[CALM_S] = state[CALM_S] + dt_s if calm else 0.0
    state[ELAPSED_S] += dt_s
    cmd = state[AVG] + spec.recovery_gain_deg * sat
    if spec.recovery_near_gain_deg > 0.0:
        # A steep inner layer: each reversal of s steps the command by up to 2 near_gain_deg, which takes up
        # the gear's lost motion; the outer gain alone (0.5 deg at 1 cm) limit-cycles on 1 deg of backlash.
        cmd += spec.recovery_near_gain_deg * min(max(surface / spec.recovery_near_phi_mps, -1.0), 1.0)
    return min(max(cmd, 0.0), spec.alpha_max_deg)


@njit(cache=True, error_model="numpy")
def recovery_settled(state: NDArray[np.float64], spec: KernelSpec) -> bool:
    """Calm for settle_time_s: hand over to the learner."""
    return state[CALM_S] >= spec.settle_time_s


@njit(cache=True, error_model="numpy")
def recovery_gave_up(state: NDArray[np.float64], spec: KernelSpec) -> bool:
    """Not settled within give_up_s."""
    return state[ELAPSED_S] >= spec.give_up_s and state[CALM_S] < spec.settle_time_s


class RecoveryController:
    """Sliding mode depth controller on s = e' + lambda e with a learned neutral angle alpha_avg."""

    def __init__(self, params: PlantParams) -> None:
        self._spec = kernel_params(params)
        self._state = np.zeros(RECOVERY_SIZE)
        recovery_init(self._state, params.alpha_max_deg / 2.0)
        self._alpha_deg = params.alpha_max_deg / 2.0
        self._update = direct_entry(recovery_update_kernel, self._state, 0.0, 0.0, 0.0, 0.0, 0.0, self._spec)
        self._settled = direct_entry(recovery_settled, self._state, self._spec)
        self._gave_up = direct_entry(recovery_gave_up, self._state, self._spec)

    @property
    def state(self) -> NDArray[np.float64]:
        """The live controller state (AVG, CALM_S, ELAPSED_S), for compiled steps that chain the kernels."""
        return self._state

    def restart(self) -> None:
        """Begin a new recovery (the settle and give-up clocks restart, alpha_avg is kept)."""
        recovery_init(self._state, self._state[AVG])

    def update(
        self, depth_m: float, velocity_mps: float, target_depth_m: float, dt_s: float,
        alpha_deg: float | None = None,
    ) -> float:
        """alpha_cmd_deg for the next period; alpha_deg (the gear angle) feeds the neutral estimate."""
        if alpha_deg is not None:
            self._alpha_deg = alpha_deg
        cmd = float(
            self._update(self._state, depth_m, velocity_mps, self._alpha_deg, target_depth_m, dt_s, self._spec)
        )
        if alpha_deg is None:
            # Without a reading of the gear, assume it follows the command (the stepper is open loop).
            self._alpha_deg = cmd
        return cmd

    @property
    def settled(self) -> bool:
        return bool(self._settled(self._state, self._spec))

    @property
    def gave_up(self) -> bool:
        return bool(self._gave_up(self._state, self._spec))

    @property
    def alpha_avg_deg(self) -> float:
        return float(self._state[AVG])
