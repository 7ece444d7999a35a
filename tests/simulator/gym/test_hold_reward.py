"""DivingAgent-v0's `reward="hold"` (issue 28 item 4): its return is the time held, so an off-the-shelf learner that
knows nothing of the task but its return learns to hold. CMA-ES (pycma, a dev dependency: pure Python) searches a
linear policy's weights on the real compiled plant for seconds; stable-baselines3's PPO does the same where it is
installed (it needs torch, 550 MB: not a dev dependency)."""

from __future__ import annotations

import gymnasium
import numpy as np
import pytest

import simulator.gym.env  # noqa: F401  registers DivingAgent-v0

SEEDS = (11, 12)


def _features(obs: np.ndarray, target_m: float) -> np.ndarray:
    """The observation scaled to about +/-1 at the learning region's edges, and a bias."""
    return np.array([(obs[0] - target_m) / 0.1, obs[1] / 0.05, obs[2] / 6.5, 1.0])


def _episode(env: gymnasium.Env, weights: np.ndarray, seed: int) -> tuple[float, float, bool]:
    """(return, time held s, success) of one episode of the policy `increase volume if w . features > 0`."""
    obs, info = env.reset(seed=seed)
    target_m = env.unwrapped.plant.target_depth_m  # type: ignore[attr-defined]
    total, done = 0.0, False
    while not done:
        action = int(np.dot(weights, _features(obs, target_m)) > 0)
        obs, reward, terminated, truncated, info = env.step(action)
        total += float(reward)
        done = terminated or truncated
    return total, float(info["time_held_s"]), bool(info["success"])


def test_cma_es_on_the_hold_return_learns_to_hold() -> None:
    import cma

    env = gymnasium.make("DivingAgent-v0", reward="hold")
    search = cma.CMAEvolutionStrategy(np.zeros(4), 1.0, {"popsize": 8, "seed": 3, "verbose": -9})
    generations: list[tuple[float, float]] = []  # (mean return, mean time held) of each generation
    for _ in range(4):
        candidates = search.ask()
        runs = [[_episode(env, np.asarray(w), seed) for seed in SEEDS[:1]] for w in candidates]
        for run in runs:
            for ret, held, _ in run:
                assert ret == pytest.approx(held, abs=1e-6)  # under "hold" the return is the time held
        generations.append((float(np.mean([r for run in runs for r, _, _ in run])),
                            float(np.mean([h for run in runs for _, h, _ in run]))))
        search.tell(candidates, [-np.mean([r for r, _, _ in run]) for run in runs])  # pycma minimises
    best = [_episode(env, np.asarray(search.result.xfavorite), seed) for seed in SEEDS]
    print(f"CMA-ES generations (return, held s): {generations}; learned policy: {best}")
    (first_return, first_held), (last_return, last_held) = generations[0], generations[-1]
    assert last_return > first_return and last_held > first_held  # return and time held rose together
    assert np.mean([held for _, held, _ in best]) > 2 * first_held


def test_ppo_on_the_hold_return_learns_to_hold() -> None:
    sb3 = pytest.importorskip("stable_baselines3", reason="stable-baselines3 not installed (it needs torch)")
    env = gymnasium.make("DivingAgent-v0", reward="hold")
    model = sb3.PPO("MlpPolicy", env, n_steps=1024, batch_size=256, seed=3, verbose=0)

    def evaluate() -> list[tuple[float, float]]:
        out = []
        for seed in SEEDS:
            obs, info = env.reset(seed=seed)
            total, done = 0.0, False
            while not done:
                action, _ = model.predict(obs, deterministic=True)
                obs, reward, terminated, truncated, info = env.step(int(action))
                total += float(reward)
                done = terminated or truncated
            out.append((total, float(info["time_held_s"])))
        return out

    before = evaluate()
    model.learn(total_timesteps=30_000)
    after = evaluate()
    for ret, held in before + after:
        assert ret == pytest.approx(held, abs=1e-6)
    assert np.mean([held for _, held in after]) > np.mean([held for _, held in before]), (before, after)


def test_the_paper_reward_stays_the_default_and_info_says_success() -> None:
    paper = gymnasium.make("DivingAgent-v0")
    _, info = paper.reset(seed=1)
    assert info["time_held_s"] == 0.0 and info["success"] is False
    fail_fast = np.array([0.0, 0.0, 0.0, 1.0])  # always increase volume: rises out of the region
    ret, held, success = _episode(paper, fail_fast, 1)
    assert not success and ret < -9.0  # the paper's terminal reward on leaving the region
    with pytest.raises(ValueError, match="reward 'time' not known"):
        gymnasium.make("DivingAgent-v0", reward="time")
