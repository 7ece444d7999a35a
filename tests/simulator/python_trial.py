"""One study trial run through the Python API (Learner and DivingEnv, the study's seeding): what the compiled
study must replay."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from learning import Learner, LearnerConfig
from simulator.gym.task import DivingEnv
from simulator.parameters import PlantParams


def python_loop_trial(params: PlantParams, config: LearnerConfig, seed: int, trial: int, episodes: int,
                      max_episode_s: float = math.inf,
                      before_end: Callable[[Learner], None] | None = None) -> list[float]:
    """Each episode's time in the region, as simulator.study.runner seeds trial `trial` of `seed`.

    `max_episode_s` cuts an episode short once past that much agent time (a cheap test needs no 300 s hold);
    `before_end` sees the learner after each episode's last step, before it ends the episode (its model then).
    """
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
            if terminated or truncated or env.time_s > max_episode_s:
                break
        if before_end is not None:
            before_end(learner)
        learner.end_episode()
        durations.append(env.time_s)
    return durations
