"""Compiled batches of control steps send and log the bytes of the fixture, however the batches are cut.

The fixture (tests/simulator/fixtures/agent_trace.json) was captured from main running one step and one link tick
per call; here the same script runs through StepBatcher, as the server runs it at --speed max.
"""

from __future__ import annotations

import json
from collections.abc import Callable

import numpy as np
import pytest

from learning import learner_preset
from protocol import FrameEncoder, FrameFlag, Mode, compiled, messages
from simulator.agent import batch_kernel as onboard_batch_kernel
from simulator.agent.batch import StepBatcher
from simulator.agent.link import AgentLink
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import PythonAgent
from simulator.agent.program import OnboardProgram
from simulator.parameters import preset
from tests.simulator import agent_trace

EXPECTED = {(t["preset"], t["seed"]): t for t in json.loads(agent_trace.FIXTURE.read_text())}


def _batched(batch_steps: int) -> Callable[[AgentLink, OnboardProgram, int], None]:
    """An `advance` for agent_trace.run: StepBatcher.run in calls of at most batch_steps steps."""
    batchers: dict[int, StepBatcher] = {}

    def advance(link: AgentLink, program: OnboardProgram, steps: int) -> None:
        batcher = batchers.setdefault(id(program), StepBatcher(program, link))
        while steps:
            done = batcher.run(min(steps, batch_steps), 2**63)
            assert 0 < done <= min(steps, batch_steps)
            steps -= done

    return advance


@pytest.mark.parametrize("batch_steps", [100_000, 7])
@pytest.mark.parametrize(("preset_name", "seed"), sorted(EXPECTED))
def test_batches_send_and_log_the_bytes_of_the_fixture(preset_name: str, seed: int, batch_steps: int) -> None:
    assert compiled.wait(300)
    trace = agent_trace.run(preset_name, seed, advance=_batched(batch_steps))
    expected = dict(EXPECTED[preset_name, seed])
    # "frames" counts write calls, one per frame when the fixture was captured; a batch writes its frames at once.
    # The same wire bytes (length and hash) hold the same frames.
    del trace["frames"], expected["frames"]
    assert trace == expected


def test_the_batch_kernel_frames_the_sample_the_protocol_defines() -> None:
    assert onboard_batch_kernel.SAMPLE_ID == messages.Sample.MSG_ID
    assert onboard_batch_kernel.SAMPLE_PAYLOAD == messages.Sample.DEFINITION.fixed_size


@pytest.mark.parametrize("learner", ["hardware", "fine41-rev14"])
def test_a_learner_the_batch_cannot_run_is_run_step_by_step(learner: str) -> None:
    """The velocity filter and the fine step are not in the compiled LEARNING batch: the agent running in batches (as
    the server does) sends the very bytes it sends run one step at a time (before, a batch used the observer's
    velocity and the plant's step for them)."""
    wires = []
    for batched in (False, True):
        wire = bytearray()
        agent = PythonAgent(preset("hardware"), learner_preset(learner), MissionConfig(), np.random.default_rng(8),
                            wire.extend, node_id=8, key=None)
        agent.receive(FrameEncoder(first_seq=1).encode(messages.StartLearning(max_episodes=0),
                                                       int(FrameFlag.ACK_REQUESTED)).wire)
        if batched:
            agent.run(4_000, 2**63)
        else:
            for _ in range(4_000):
                agent.step()
        assert agent.program.mode == Mode.LEARNING or agent.program.learner.episode > 0
        wires.append(bytes(wire))
    assert wires[0] == wires[1]
