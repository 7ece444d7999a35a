"""The Gymnasium-style environment: determinism, the episode ends, the reward."""

from __future__ import annotations

import numpy as np
import pytest

from learning import LearnerConfig
from simulator.errors import SimulatorError
from simulator.gym.task import DivingEnv
from simulator.parameters import preset

CONFIG = LearnerConfig()


def _rollout(env: DivingEnv, seed: int, steps: int) -> list[tuple]:
    obs, info = env.reset(seed=seed)
    out = [tuple(obs)]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(int(rng.integers(2)))
        out.append((*obs, reward, terminated))
        if terminated or truncated:
            obs, info = env.reset()
    return out


@pytest.mark.parametrize("name", ["paper", "hardware"])
def test_same_seed_same_trajectory(name: str) -> None:
    a = _rollout(DivingEnv(preset(name), CONFIG), 7, 300)
    b = _rollout(DivingEnv(preset(name), CONFIG), 7, 300)
    c = _rollout(DivingEnv(preset(name), CONFIG), 8, 300)
    assert a == b and a != c


def test_episode_starts_inside_the_region_at_rest() -> None:
    env = DivingEnv(preset("paper"), CONFIG)
    for seed in range(20):
        obs, info = env.reset(seed=seed)
        assert abs(info["depth_m"] - preset("paper").target_depth_m) < 0.095 + 0.003
        assert info["velocity_mps"] == 0.0 and info["state"] < 100


def test_leaving_the_region_terminates_with_the_terminal_reward() -> None:
    env = DivingEnv(preset("paper"), CONFIG)
    env.reset(seed=1)
    terminated = truncated = False
    reward = 0.0
    while not (terminated or truncated):
        _, reward, terminated, truncated, info = env.step(0)  # keep decreasing volume: it sinks out
    assert terminated and not truncated and reward == -10.0 and info["state"] == 100
    with pytest.raises(SimulatorError):
        env.step(0)


def test_surviving_300s_is_a_truncation_not_a_terminal() -> None:
    env = DivingEnv(preset("paper"), LearnerConfig(z_tol_m=50.0, zdot_tol_mps=50.0))
    env.reset(seed=1)
    steps = 0
    while True:
        _, reward, terminated, truncated, _ = env.step(steps % 2)
        steps += 1
        if terminated or truncated:
            break
    assert truncated and not terminated and steps == 3000 and env.time_s == pytest.approx(300.0)
    assert reward > -10.0


def test_hardware_episodes_begin_after_the_recovery_controller_settles() -> None:
    env = DivingEnv(preset("hardware"), CONFIG)
    obs, info = env.reset(seed=3)
    assert info["recovery_s"] >= preset("hardware").settle_time_s
    assert abs(obs[1]) < 0.01 and info["state"] < 100
