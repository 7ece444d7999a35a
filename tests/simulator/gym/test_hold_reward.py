"""DivingAgent-v0's `reward="hold"` (issue 28 item 4): its return is the time held, so a learner that knows
nothing of the task but its return learns to hold. A small cross-entropy learner written here (stable-baselines3
needs torch, not installed), over a linear policy, trained for seconds on the real compiled plant."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import simulator.gym.env  # noqa: F401  registers DivingAgent-v0


def _episode(env: gymnasium.Env, weights: np.ndarray, seed: int) -> tuple[float, float, bool]:
    """(return, time held s, success) of one episode of the policy `increase volume if w . [obs, 1] > 0`."""
    obs, info = env.reset(seed=seed)
    total, done = 0.0, False
    while not done:
        action = int(np.dot(weights[:3], obs) + weights[3] > 0)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        done = terminated or truncated
    return total, float(info["time_held_s"]), bool(info["success"])


def test_the_hold_return_is_the_time_held_and_a_learner_improves_both() -> None:
    env = gymnasium.make("DivingAgent-v0", reward="hold")
    rng = np.random.default_rng(7)
    mean, spread = np.zeros(4), np.ones(4) * 2.0
    seeds = (11, 12)
    history: list[tuple[float, float]] = []
    first_generation = None
    for _generation in range(5):
        population = mean + spread * rng.standard_normal((10, 4))
        scores = []
        for weights in population:
            runs = [_episode(env, weights, seed) for seed in seeds]
            history += [(ret, held) for ret, held, _ in runs]
            scores.append(np.mean([ret for ret, _, _ in runs]))
        first_generation = np.mean(scores) if first_generation is None else first_generation
        elite = population[np.argsort(scores)[-3:]]
        mean, spread = elite.mean(axis=0), elite.std(axis=0) + 0.1
    returns, held = np.array(history).T
    np.testing.assert_allclose(returns, held, atol=1e-6)  # under "hold" the return is the time held, exactly
    trained = np.mean([_episode(env, mean, seed)[1] for seed in seeds])
    print(f"time held: first generation {first_generation:.1f} s, trained {trained:.1f} s")
    assert trained > first_generation  # learning the return learned to hold longer


def test_the_paper_reward_stays_the_default_and_info_says_success() -> None:
    paper = gymnasium.make("DivingAgent-v0")
    _, info = paper.reset(seed=1)
    assert info["time_held_s"] == 0.0 and info["success"] is False
    fail_fast = np.array([0.0, 0.0, 0.0, 1.0])  # always increase volume: rises out of the region
    ret, held, success = _episode(paper, fail_fast, 1)
    assert not success and ret < -9.0  # the paper's terminal reward on leaving the region
    with pytest.raises(ValueError, match="reward 'time' not known"):
        gymnasium.make("DivingAgent-v0", reward="time")
