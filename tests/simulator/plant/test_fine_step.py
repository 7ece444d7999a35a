"""Issue 43: the fine41 learner's step is 0.7 deg while the velocity it sees is under 16 mm/s, the plant's 2.1 deg
otherwise (LearnerConfig.fine_step_deg), inside the actuator window as before."""

from __future__ import annotations

import numpy as np

from learning.presets import learner_preset
from simulator.gym.task import DivingEnv
from simulator.parameters import preset


def test_the_step_is_fine_at_a_hover_and_full_when_moving() -> None:
    params, config = preset("hardware"), learner_preset("fine41")
    env = DivingEnv(params, config)
    obs, info = env.reset(seed=3)
    rng = np.random.default_rng(3)
    steps: dict[bool, set[float]] = {True: set(), False: set()}
    for _ in range(3000):
        slow = abs(obs[1]) < config.fine_speed_mps
        before = info["alpha_cmd_deg"]
        obs_next, _, terminated, truncated, info = env.step(int(rng.integers(2)))
        moved = round(abs(info["alpha_cmd_deg"] - before), 6)
        at_edge = abs(obs_next[2]) >= params.action_window_deg - 1e-9  # clipped by the window
        if not at_edge and not (terminated or truncated):
            steps[slow].add(moved)
        obs = obs_next
        if terminated or truncated:
            obs, info = env.reset()
    assert steps[True] == {config.fine_step_deg}
    assert steps[False] == {params.action_step_deg}


def test_a_reversal_near_a_hover_steps_fine_reversal_deg() -> None:
    """LearnerConfig.fine_reversal_deg: near a hover an action that reverses the last one steps 1.4 deg (taking up a
    gear's lash), one that continues 0.7 deg; away from a hover every step is the plant's 2.1 deg; the first action
    of an episode counts as a reversal."""
    params = preset("hardware")
    config = learner_preset("fine41", fine_reversal_deg=1.4)
    env = DivingEnv(params, config)
    obs, info = env.reset(seed=3)
    rng = np.random.default_rng(4)
    last = -1
    steps: dict[tuple[bool, bool], set[float]] = {}
    for _ in range(3000):
        action = int(rng.integers(2))
        slow = abs(obs[1]) < config.fine_speed_mps
        before = info["alpha_cmd_deg"]
        obs_next, _, terminated, truncated, info = env.step(action)
        moved = round(abs(info["alpha_cmd_deg"] - before), 6)
        if abs(obs_next[2]) < params.action_window_deg - 1e-9 and not (terminated or truncated):
            steps.setdefault((slow, action != last), set()).add(moved)
        obs, last = obs_next, action
        if terminated or truncated:
            obs, info = env.reset()
            last = -1
    assert steps[(True, False)] == {config.fine_step_deg}
    assert steps[(True, True)] == {config.fine_reversal_deg}
    assert steps[(False, True)] == steps[(False, False)] == {params.action_step_deg}
