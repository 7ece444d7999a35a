"""A Gymnasium-style environment of the learner's task, over the compiled episode kernels."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from learning import LearnerConfig
from learning.config import MAX_VELOCITY_DIFF_STEPS, kernel_spec
from learning.rng import new_stream
from simulator.errors import SimulatorError
from simulator.parameters import PlantParams, kernel_params
from simulator.plant.episode import (
    E_ALPHA,
    E_CENTER,
    E_CMD,
    E_DEPTH_MEAS,
    E_FILT_V,
    E_FILT_Z,
    E_OBS_X1,
    E_OBS_X2,
    E_PLANT_END,
    E_RECOVERY_S,
    E_RING,
    E_STEPS,
    E_VEL_EST,
    E_Z,
    E_ZDOT,
    episode_cell_kernel,
    episode_reset_kernel,
    episode_state_kernel,
    episode_step_kernel,
    new_env_state,
)
from simulator.plant.kernel import plant_place

# reset(options={"start": {...}}): a recorded state to start from (a recording replayed through the plant)
START_KEYS = ("depth_m", "velocity_mps", "alpha_deg", "alpha_cmd_deg", "centre_deg")


class DivingEnv:
    """reset(*, seed, options) -> (obs, info); step(action) -> (obs, reward, terminated, truncated, info).

    obs = [measured depth m, velocity the learner sees m/s, alpha_cmd - window centre deg];
    info["state"] is the learner's state index;
    info["cell"] its unclipped cell (learning.shared). One random stream per environment.
    """

    def __init__(
        self, params: PlantParams, config: LearnerConfig, rng: np.random.Generator | None = None
    ) -> None:
        self.params = params
        self.config = config
        self._spec = kernel_params(params)
        self._lspec = kernel_spec(config)
        self._rng_state = new_stream(rng if rng is not None else np.random.default_rng())
        self._env = new_env_state(self._spec)
        self._ready = False

    def reset(
        self, *, seed: int | Sequence[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        """Start an episode; a seed restarts the stream and the plant, so the same seed repeats exactly.

        options={"start": {depth_m, velocity_mps, alpha_deg, alpha_cmd_deg, centre_deg}} starts it from that state
        instead (a recorded episode's first SAMPLE: its actions replayed then retrace it, within the sensor's noise).
        """
        if seed is not None:
            self._rng_state = new_stream(np.random.default_rng(seed))
            self._env = new_env_state(self._spec)
        state = int(
            episode_reset_kernel(
                self._env, self.params.target_depth_m, self._spec, self._lspec, self._rng_state
            )
        )
        start = (options or {}).get("start")
        if start is not None:
            state = self._place(start)
        self._ready = True
        return self._obs(), self._info(state)

    def _place(self, start: dict[str, float]) -> int:
        missing = [key for key in START_KEYS if key not in start]
        if missing:
            raise SimulatorError(f"options['start'] lacks {', '.join(missing)}")
        e = self._env
        depth, velocity = float(start["depth_m"]), float(start["velocity_mps"])
        plant_place(e[:E_PLANT_END], depth, velocity, float(start["alpha_deg"]))
        e[E_CMD], e[E_CENTER] = float(start["alpha_cmd_deg"]), float(start["centre_deg"])
        # The agent has measured this depth and believes this velocity: so does its observer, and its depth history.
        e[E_OBS_X1], e[E_OBS_X2], e[E_DEPTH_MEAS], e[E_VEL_EST] = depth, velocity, depth, velocity
        e[E_RING:E_RING + MAX_VELOCITY_DIFF_STEPS] = depth
        e[E_FILT_Z], e[E_FILT_V] = depth, velocity
        return int(episode_state_kernel(e, self.params.target_depth_m, self._spec, self._lspec))

    def step(self, action: int) -> tuple[NDArray[np.float64], float, bool, bool, dict[str, Any]]:
        """One control period with action 0 (decrease volume) or 1 (increase volume)."""
        if not self._ready:
            raise SimulatorError("call reset() before step() (and after an episode ends)")
        if action not in (0, 1):
            raise SimulatorError(f"action must be 0 or 1, got {action}")
        state, reward, terminated, truncated = episode_step_kernel(
            self._env, int(action), self.params.target_depth_m, self._spec, self._lspec, self._rng_state
        )
        if terminated or truncated:
            self._ready = False
        return self._obs(), float(reward), bool(terminated), bool(truncated), self._info(int(state))

    @property
    def time_s(self) -> float:
        """Time since the episode began."""
        return float(self._env[E_STEPS]) * self.params.control_period_s

    def _obs(self) -> NDArray[np.float64]:
        e = self._env
        return np.array([e[E_DEPTH_MEAS], e[E_VEL_EST], e[E_CMD] - e[E_CENTER]])

    def _info(self, state: int) -> dict[str, Any]:
        e = self._env
        return {
            "state": state,
            # The unclipped grid cell of the measurement: the shared model's successor, inside or out.
            "cell": int(episode_cell_kernel(e, self.params.target_depth_m, self._spec, self._lspec)),
            "time_s": self.time_s,
            "depth_m": float(e[E_Z]),
            "velocity_mps": float(e[E_ZDOT]),
            "alpha_deg": float(e[E_ALPHA]),
            "alpha_cmd_deg": float(e[E_CMD]),
            "recovery_s": float(e[E_RECOVERY_S]),
        }
