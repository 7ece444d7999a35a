"""DivingAgent-v0 through Gymnasium itself: the env checker, spaces, seeding, wrappers, rendering."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import simulator.gym  # noqa: F401  registers DivingAgent-v0
from simulator.gym.env import DiscreteState, DivingAgentEnv, ObserverInTheLoop


def _check(env: gymnasium.Env) -> None:
    with warnings.catch_warnings():
        # The checker recommends checking the unwrapped env; the wrappers are what we check here.
        warnings.filterwarnings("ignore", message=".*different from the unwrapped.*")
        check_env(env, skip_render_check=False)


@pytest.mark.parametrize("preset", ["paper", "hardware"])
def test_env_passes_gymnasiums_checker(preset: str) -> None:
    env = gymnasium.make("DivingAgent-v0", preset=preset, render_mode="rgb_array")
    _check(env.unwrapped)
    assert env.action_space == gymnasium.spaces.Discrete(2)
    assert env.observation_space.shape == (3,)


def test_wrappers_pass_the_checker_and_give_the_papers_state() -> None:
    discrete = DiscreteState(gymnasium.make("DivingAgent-v0", preset="paper"))
    _check(discrete)
    assert discrete.observation_space == gymnasium.spaces.Discrete(101)
    state, info = discrete.reset(seed=4)
    assert 0 <= state < 100 and state == info["state"]  # starts inside the region, never terminal
    observed = ObserverInTheLoop(gymnasium.make("DivingAgent-v0", preset="paper"))
    _check(observed)
    assert observed.unwrapped.plant.use_observer  # type: ignore[attr-defined]
    _, info = observed.reset(seed=1)
    assert "velocity_mps" not in info and "depth_m" not in info  # nothing from outside the robot


def test_make_kwargs_reach_the_task() -> None:
    env = gymnasium.make("DivingAgent-v0", preset="hardware", z_tol_m=0.15, zdot_tol_mps=0.03,
                         params={"target_depth_m": 0.5})
    base = env.unwrapped
    assert isinstance(base, DivingAgentEnv)
    assert (base.config.z_tol_m, base.config.zdot_tol_mps, base.plant.target_depth_m) == (0.15, 0.03, 0.5)
    with pytest.raises(TypeError, match="unknown option"):
        gymnasium.make("DivingAgent-v0", z_tol=0.1)


def _trajectory(seed: int) -> list[tuple[float, ...]]:
    env = gymnasium.make("DivingAgent-v0", preset="hardware")
    obs, _ = env.reset(seed=seed)
    out = [tuple(obs)]
    for step in range(200):
        obs, reward, terminated, truncated, _ = env.step(step % 2)
        out.append((*obs, float(reward)))
        if terminated or truncated:
            obs, _ = env.reset()
    return out


def test_same_seed_same_trajectory() -> None:
    assert _trajectory(11) == _trajectory(11)
    assert _trajectory(11) != _trajectory(12)


def test_rgb_array_shows_the_episode() -> None:
    env = gymnasium.make("DivingAgent-v0", preset="paper", render_mode="rgb_array")
    env.reset(seed=0)
    first = env.render()
    for _ in range(30):
        env.step(1)
    image = env.render()
    assert isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.shape[2] == 3
    assert image.std() > 10 and not np.array_equal(first, image)  # a picture, and it moves


def test_tabular_example_learns_through_the_gymnasium_api() -> None:
    from examples.gym_tabular_q import train

    durations = train(episodes=8, seed=0, preset="paper")
    assert len(durations) == 8 and all(0.0 < d <= 300.0 for d in durations)


def test_the_environment_is_reached_by_its_package_and_by_its_old_path() -> None:
    """gymnasium's module:id form imports simulator.gym itself; simulator.gym_env is the old path's alias."""
    script = ("import gymnasium; env = gymnasium.make('simulator.gym:DivingAgent-v0'); "
              "import simulator.gym_env as old; import simulator.gym.env as new; "
              "assert old.DivingAgentEnv is new.DivingAgentEnv; print(type(env.unwrapped).__name__)")
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "DivingAgentEnv"
