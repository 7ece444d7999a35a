"""The learner's velocity filter (issue 29): less lag than the 8-step difference behind a lagging, noisier port."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from learning import LearnerConfig, learner_preset
from learning.acting import state_index_kernel
from learning.config import kernel_spec
from learning.errors import LearnerConfigError
from simulator.gym.task import DivingEnv
from simulator.parameters import preset, with_overrides
from simulator.plant.observer import VelocityFilter

FILTER = "shared-z20-bins7-filter-term100-vpen1"
DIFFERENCE = "shared-z20-bins7-diff8-term100-vpen1"  # the hardware learner before the filter


def _velocity_errors(config: LearnerConfig, overrides: dict[str, float], steps: int = 400) -> tuple[float, float]:
    """(RMS, worst) |learner's velocity - true velocity| in m/s while a bang-bang swing (the limit cycle a
    two-action learner runs) drives the hull: 1.5 s one way, 1.5 s the other."""
    env = DivingEnv(with_overrides(preset("hardware"), overrides), config)
    env.reset(seed=3)
    errors = []
    for k in range(steps):
        obs, _, terminated, truncated, info = env.step((k // 15) % 2)
        errors.append(obs[1] - info["velocity_mps"])
        if terminated or truncated:
            env.reset()
    e = np.abs(np.array(errors[20:]))  # past the first 2 s, when the difference's history is still flat
    return float(np.sqrt(np.mean(e * e))), float(e.max())


@pytest.mark.parametrize("overrides", [{}, {"pressure_lag_s": 0.2}, {"pressure_noise_pa": 13.0}])
def test_the_filter_follows_the_true_velocity_closer_than_the_depth_difference(overrides: dict[str, float]) -> None:
    filtered = _velocity_errors(learner_preset(FILTER), overrides)
    difference = _velocity_errors(learner_preset(DIFFERENCE), overrides)
    assert filtered[0] < 0.6 * difference[0], (filtered, difference)
    assert filtered[1] < difference[1], (filtered, difference)


def test_the_filter_is_off_by_default_and_excludes_the_depth_difference() -> None:
    assert LearnerConfig().filter_depth_gain == 0.0
    assert learner_preset(DIFFERENCE).filter_depth_gain == 0.0
    with pytest.raises(LearnerConfigError, match="needs the velocity filter"):
        LearnerConfig(filter_depth_state=True)
    with pytest.raises(LearnerConfigError, match="not both"):
        replace(learner_preset(FILTER), velocity_diff_steps=8)
    with pytest.raises(LearnerConfigError, match="negative"):
        replace(learner_preset(FILTER), filter_bias_gain=-0.1)


@pytest.mark.parametrize("learner", [FILTER, "hardware"])
def test_the_agents_filter_is_the_study_kernels(learner: str) -> None:
    """simulator/agent's VelocityFilter gives the compiled episode's velocity on the same readings and commands, and
    with filter_depth_state (the hardware learner) its depth is the one the episode's state is made of."""
    config = learner_preset(learner)
    params = with_overrides(preset("hardware"), {"pressure_lag_s": 0.2})
    env = DivingEnv(params, config)
    obs, _ = env.reset(seed=4)
    twin = VelocityFilter(config)
    twin.reset(obs[0])
    ends = 0
    spec = kernel_spec(config)
    for k in range(600):
        obs, _, terminated, truncated, info = env.step((k // 15) % 2)
        assert twin.update(obs[0], obs[2], params.control_period_s) == pytest.approx(obs[1], abs=1e-12), k
        seen = twin.depth_m if config.filter_depth_state else obs[0]
        fraction = obs[2] / params.action_window_deg
        assert state_index_kernel(seen, obs[1], params.target_depth_m, fraction, spec) == info["state"], k
        if terminated or truncated:
            obs, _ = env.reset()
            twin.reset(obs[0])
            ends += 1
    assert ends > 0
