"""Train a plain tabular Q-learner on `DivingAgent-v0` through Gymnasium's API only.

    python examples/gym_tabular_q.py --episodes 200

Any Gymnasium-compatible learner works the same way: `gymnasium.make("DivingAgent-v0", ...)`, then
`reset(seed=...)` / `step(action)`. This one is deliberately simple (epsilon-greedy Q-learning on the
paper's discrete state), not the project's model-based learner; it prints the time each episode held
the depth, the paper's learning curve.
"""

from __future__ import annotations

import argparse

import gymnasium
import numpy as np

import simulator.gym  # noqa: F401  registers DivingAgent-v0
from simulator.gym.env import DiscreteState


def train(episodes: int, seed: int, preset: str) -> list[float]:
    """Episode durations in seconds, one per episode."""
    env = DiscreteState(gymnasium.make("DivingAgent-v0", preset=preset))
    n_states = int(env.observation_space.n)  # type: ignore[attr-defined]
    q = np.zeros((n_states, 2))
    rng = np.random.default_rng(seed)
    alpha, gamma = 0.2, 0.99
    durations: list[float] = []
    state, info = env.reset(seed=seed)
    for episode in range(episodes):
        epsilon = max(0.01, 0.2 * (1.0 - episode / max(episodes, 1)))
        done = False
        while not done:
            ties = np.flatnonzero(q[state] == q[state].max())
            action = int(rng.integers(2)) if rng.random() < epsilon else int(rng.choice(ties))
            next_state, reward, terminated, truncated, info = env.step(np.int64(action))
            target = float(reward) + (0.0 if terminated else gamma * q[next_state].max())
            q[state, action] += alpha * (target - q[state, action])
            state, done = next_state, terminated or truncated
        durations.append(float(info["time_s"]))
        state, info = env.reset()
    env.close()
    return durations


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--preset", default="paper", choices=["paper", "hardware"])
    args = parser.parse_args()
    durations = train(args.episodes, args.seed, args.preset)
    for start in range(0, len(durations), 10):
        window = durations[start:start + 10]
        print(f"episodes {start + 1:4d}-{start + len(window):4d}: mean hold {np.mean(window):6.1f} s, "
              f"best {max(window):6.1f} s")


if __name__ == "__main__":
    main()
