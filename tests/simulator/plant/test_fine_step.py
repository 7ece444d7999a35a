"""Issue 43: the fine41 learner's step is 0.7 deg while the velocity it sees is under 16 mm/s, the plant's 2.1 deg
otherwise (LearnerConfig.fine_step_deg), inside the actuator window as before; with fine_reversal_deg a reversal near
a hover steps that instead, in the environment and in the virtual agent alike."""

from __future__ import annotations

from itertools import pairwise

import numpy as np
import pytest

from learning.presets import learner_preset
from protocol import FrameEncoder, FrameFlag, Mode, StreamDecoder, messages
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import PythonAgent
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


@pytest.mark.parametrize("batched", [False, True])
def test_the_virtual_agent_steps_the_reversal_step(batched: bool) -> None:
    """The virtual agent (simulator/agent/modes.py) learning with fine41-rev14 takes the same three step sizes as the
    environment: in its LEARNING SAMPLEs a step near a hover moves the command 1.4 deg where the action reverses the
    last one (or starts the episode) and 0.7 deg where it continues; elsewhere 2.1 deg. Also when run in batches as
    the server runs it (PythonAgent.run), whose compiled LEARNING batch knows no fine step."""
    params = preset("hardware")
    config = learner_preset("fine41-rev14")
    decoder = StreamDecoder()
    samples: list[messages.Sample] = []

    def wrote(wire: bytes) -> None:
        samples.extend(f.message for f in decoder.feed(wire) if isinstance(f.message, messages.Sample))

    agent = PythonAgent(params, config, MissionConfig(), np.random.default_rng(6), wrote, node_id=6, key=None)
    agent.receive(FrameEncoder(first_seq=1).encode(messages.StartLearning(max_episodes=0),
                                                  int(FrameFlag.ACK_REQUESTED)).wire)
    if batched:
        agent.run(12_000, 10**15)
    else:
        for _ in range(12_000):
            agent.step()
    seen: dict[float, int] = {}
    for before, after in pairwise(samples):
        if not (after.mode == Mode.LEARNING and after.action in (0, 1)):
            continue
        first = before.mode != Mode.LEARNING or before.episode != after.episode
        moved = round(abs(after.actuator_cmd_deg - before.actuator_cmd_deg), 4)
        slow = abs(after.velocity_mps) < config.fine_speed_mps
        reversal = first or after.action != before.action
        expected = (config.fine_reversal_deg if reversal else config.fine_step_deg) if slow else params.action_step_deg
        if moved in (config.fine_step_deg, config.fine_reversal_deg, params.action_step_deg):  # not clamped
            assert moved == expected, (after.sample, after.velocity_mps, reversal, moved)
            seen[expected] = seen.get(expected, 0) + 1
    assert len(seen) == 3 and min(seen.values()) > 20, seen
