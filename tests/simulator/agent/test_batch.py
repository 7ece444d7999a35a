"""Compiled batches of control steps send and log the bytes of the fixture, however the batches are cut.

The fixture (tests/simulator/fixtures/agent_trace.json) was captured from main running one step and one link tick
per call; here the same script runs through StepBatcher, as the server runs it at --speed max.
"""

from __future__ import annotations

import json
from collections.abc import Callable

import pytest

from protocol import compiled, messages
from simulator.agent import batch_kernel as onboard_batch_kernel
from simulator.agent.batch import StepBatcher
from simulator.agent.link import AgentLink
from simulator.agent.program import OnboardProgram
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
