"""One study trial run through the Python API (Learner and DivingEnv, the study's seeding): what the compiled
study must replay."""

from __future__ import annotations

import numpy as np

from learning import Learner, LearnerConfig
from simulator.gym.task import DivingEnv
from simulator.parameters import PlantParams


def python_loop_trial(params: PlantParams, config: LearnerConfig, seed: int, trial: int, episodes: int) -> list[float]:
    """Each episode's time in the region, as simulator.study.runner seeds trial `trial` of `seed`."""
    learner = Learner(config, np.random.default_rng([seed, trial, 0]))
    env = DivingEnv(params, config, np.random.default_rng([seed, trial, 1]))
    durations = []
    for _ in range(episodes):
        _, info = env.reset()
        state = info["state"]
        while True:
            action = learner.act(state)
            _, reward, terminated, truncated, info = env.step(action)
            # The raw cell is what a shared model needs for a terminal successor; the other learners ignore it.
            learner.observe(state, action, reward, info["state"], info["cell"])
            state = info["state"]
            if terminated or truncated:
                break
        learner.end_episode()
        durations.append(env.time_s)
    return durations
