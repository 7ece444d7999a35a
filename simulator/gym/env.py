"""`DivingAgent-v0`: the learner's task as a real `gymnasium.Env`, with wrappers for the paper's state.

    import gymnasium, simulator.gym.env
    env = gymnasium.make("DivingAgent-v0", preset="hardware", z_tol_m=0.15, zdot_tol_mps=0.03)

or, without importing first, `gymnasium.make("simulator.gym.env:DivingAgent-v0")`. Keyword arguments
of `make`: `preset` (`paper` or `hardware`), `learner` (a named learner of `learning.presets`, for
the grid), every `LearnerConfig` field the task depends on (z_tol_m, zdot_tol_mps, z_cells,
zdot_cells, actuator_bins, terminal_reward, depth_only_terminal), `params` (PlantParams overrides as
a dict, e.g. {"target_depth_m": 0.5}) and `render_mode` (`"rgb_array"`).

Observation: [measured depth m, velocity the learner sees m/s, actuator command minus the window's
centre deg]: what the agent itself knows. With the `hardware` preset the velocity is the sliding
mode observer's estimate (the observer is in the loop); with `paper` it is the true velocity, as
the paper's simulation had it. Episode ends are the paper's (terminated on leaving the learning
region, truncated at the success time: a success).

Reward, `reward=` of `make`:
- `"paper"` (default): the paper's (eq. 2), -|z - z_d| per step and `terminal_reward` (-10) on leaving
  the region. It serves the paper's planner, but its return is no measure of success: a 300 s success
  returns about -30, a failure after a second about -11, so an off-the-shelf agent maximising return
  learns to fail fast.
- `"hold"`: +control period (0.1 s) for every step that ends inside the region, 0 on the step that
  leaves it: the return is the time held in seconds, largest for a success. Use it to train
  Gymnasium agents (PPO, DQN ...) on the task.

`reset(options={"start": {"depth_m", "velocity_mps", "alpha_deg", "alpha_cmd_deg", "centre_deg"}})` starts an
episode from a recorded state: a recorded episode's actions replayed from its first SAMPLE retrace it within the
sensor's noise in the environment a Minari export's `recover_environment()` rebuilds (tests/groundstation/recording/
test_minari_groups.py).

`info` carries `success` (the episode ended by holding for the success time) and `time_held_s` (time
in the region so far) under either reward.
"""

from __future__ import annotations

from typing import Any, SupportsFloat

import gymnasium
import numpy as np
from gymnasium import spaces
from numpy.typing import NDArray

from learning import LearnerConfig, n_states
from learning.presets import learner_preset
from simulator.gym.task import DivingEnv
from simulator.parameters import PlantParams, preset, with_overrides

# What the real agent can measure or command, with margin: the sensor reads to ~2.9 m (MS5803-01BA),
# velocities past 5 m/s and gear offsets past the 130 deg stroke cannot happen.
OBS_LOW = np.array([-1.0, -5.0, -130.0])
OBS_HIGH = np.array([12.0, 5.0, 130.0])
_LEARNER_FIELDS = (
    "z_tol_m", "zdot_tol_mps", "z_cells", "zdot_cells", "actuator_bins", "terminal_reward",
    "depth_only_terminal",
)
REWARDS = ("paper", "hold")  # see the module docstring
_RENDER_STEPS = 3000  # the last 300 s at 0.1 s: one successful episode


class DivingAgentEnv(gymnasium.Env[NDArray[np.float64], np.int64]):
    """The depth-holding task of the paper over the project's compiled plant (simulator.gym.task.DivingEnv)."""

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(
        self, preset_name: str = "paper", learner: str = "paper", params: dict[str, Any] | None = None,
        render_mode: str | None = None, reward: str = "paper", **learner_options: Any,
    ) -> None:
        if reward not in REWARDS:
            raise ValueError(f"reward {reward!r} not known; use one of {', '.join(REWARDS)}")
        self.reward = reward
        unknown = sorted(set(learner_options) - set(_LEARNER_FIELDS))
        if unknown:
            raise TypeError(f"unknown option(s) {', '.join(unknown)}; choose from {', '.join(_LEARNER_FIELDS)}")
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode {render_mode!r} not supported; use 'rgb_array' or None")
        plant: PlantParams = preset(preset_name)
        if params:
            plant = with_overrides(plant, params)
        self.config: LearnerConfig = learner_preset(learner, **learner_options)
        self.plant = plant
        self.render_mode = render_mode
        self._task = DivingEnv(plant, self.config)
        self._seeded = False
        self.observation_space = spaces.Box(OBS_LOW, OBS_HIGH, dtype=np.float64)
        self.action_space = spaces.Discrete(2)  # 0 decrease volume, 1 increase volume (paper's a1, a2)
        self._trace: list[tuple[float, float, float]] = []  # (time s, depth m, actuator offset deg)

    @property
    def n_states(self) -> int:
        """Number of discrete learner states, terminal included (101 with the paper's grid)."""
        return n_states(self.config)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        super().reset(seed=seed)
        if seed is None and not self._seeded:
            # Gymnasium seeded np_random from entropy: derive the plant's stream from it, once.
            seed = int(self.np_random.integers(2**63))
        self._seeded = True
        obs, info = self._task.reset(seed=seed, options=options)  # options={"start": ...}: task.py
        self._trace = [(0.0, float(obs[0]), float(obs[2]))]
        info["time_held_s"], info["success"] = 0.0, False
        return self._clip(obs), info

    def step(
        self, action: np.int64 | int
    ) -> tuple[NDArray[np.float64], SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self._task.step(int(action))
        self._trace.append((float(info["time_s"]), float(obs[0]), float(obs[2])))
        del self._trace[:-_RENDER_STEPS]
        period_s = self.plant.control_period_s
        # The step that leaves the region is not time held; every step before it, and every step of a success, is.
        info["time_held_s"] = float(info["time_s"]) - (period_s if terminated else 0.0)
        info["success"] = bool(truncated and not terminated)
        if self.reward == "hold":
            reward = 0.0 if terminated else period_s
        return self._clip(obs), reward, terminated, truncated, info

    def render(self) -> NDArray[np.uint8] | None:  # type: ignore[override]
        """An RGB image of the episode so far: depth with target and bounds, and the actuator offset."""
        if self.render_mode != "rgb_array":
            return None
        from simulator.gym.render import episode_image

        return episode_image(self._trace, self.plant.target_depth_m, self.config.z_tol_m,
                             self.plant.action_window_deg)

    def _clip(self, obs: NDArray[np.float64]) -> NDArray[np.float64]:
        return np.clip(obs, OBS_LOW, OBS_HIGH)


class DiscreteState(
    gymnasium.Wrapper[np.int64, np.int64, NDArray[np.float64], np.int64], gymnasium.utils.RecordConstructorArgs
):
    """The paper's discrete state (Fig. 2: a grid cell of the learning region, S-1 terminal) as the
    observation: what the on-board learner sees. `Discrete(S)`, S = 101 with the paper's grid."""

    def __init__(self, env: gymnasium.Env[NDArray[np.float64], np.int64]) -> None:
        gymnasium.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)  # type: ignore[arg-type]  # gymnasium annotates it with the wrapper's types
        base = env.unwrapped
        if not isinstance(base, DivingAgentEnv):
            raise TypeError("DiscreteState wraps a DivingAgent-v0 environment")
        self.observation_space = spaces.Discrete(base.n_states)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.int64, dict[str, Any]]:
        _, info = self.env.reset(seed=seed, options=options)
        # The environment computes the state from the same observation (simulator.plant.episode._state).
        return np.int64(info["state"]), info

    def step(self, action: np.int64) -> tuple[np.int64, SupportsFloat, bool, bool, dict[str, Any]]:
        _, reward, terminated, truncated, info = self.env.step(action)
        return np.int64(info["state"]), reward, terminated, truncated, info


class ObserverInTheLoop(
    gymnasium.Wrapper[NDArray[np.float64], np.int64, NDArray[np.float64], np.int64],
    gymnasium.utils.RecordConstructorArgs,
):
    """The real agent's view: velocity from the sliding mode observer (the hardware preset's plant
    with the observer switched on whatever the preset), and `info` stripped of the true plant state,
    so nothing a learner uses comes from outside the robot."""

    _HIDDEN = ("depth_m", "velocity_mps", "alpha_deg")

    def __init__(self, env: gymnasium.Env[NDArray[np.float64], np.int64]) -> None:
        base = env.unwrapped
        if not isinstance(base, DivingAgentEnv):
            raise TypeError("ObserverInTheLoop wraps a DivingAgent-v0 environment")
        if not base.plant.use_observer:
            base.plant = with_overrides(base.plant, {"use_observer": True})
            base._task = DivingEnv(base.plant, base.config)
        gymnasium.utils.RecordConstructorArgs.__init__(self)
        super().__init__(env)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.float64], dict[str, Any]]:
        obs, info = self.env.reset(seed=seed, options=options)
        return obs, self._strip(info)

    def step(
        self, action: np.int64
    ) -> tuple[NDArray[np.float64], SupportsFloat, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return obs, reward, terminated, truncated, self._strip(info)

    def _strip(self, info: dict[str, Any]) -> dict[str, Any]:
        return {k: v for k, v in info.items() if k not in self._HIDDEN}


def _make(preset: str = "paper", **kwargs: Any) -> DivingAgentEnv:
    return DivingAgentEnv(preset_name=preset, **kwargs)

