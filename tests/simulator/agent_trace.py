"""A deterministic trace of the virtual agent: every wire byte and on-board log record for a seed and a command script.

The agent is built as `simulator.serve.loop.AgentServer` builds it (same seeding, same link and program), without
a transport: the script says after which control step each ground frame arrives, so the trace does not depend
on wall time. `python -m tests.simulator.agent_trace` prints the fixture the byte-identity test compares with.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from learning import LearnerConfig, learner_preset
from protocol import DumpKind, FrameEncoder, messages
from protocol.registry import Message
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.link import AgentLink
from simulator.agent.log_ring import LogRing
from simulator.agent.mission import MissionConfig
from simulator.agent.program import OnboardProgram
from simulator.parameters import preset

FIXTURE = Path(__file__).parent / "fixtures" / "agent_trace.json"

# (control steps to run first, ground frame to deliver then). Covers every mode, replies and log replay.
SCRIPT: tuple[tuple[int, Message], ...] = (
    (5, messages.Hello(protocol_version=1, node_kind=2)),
    (3, messages.Timesync(origin_us=12345)),
    (20, messages.StartLearning(max_episodes=0)),
    (8_000, messages.DumpRequest(kind=int(DumpKind.VALUES))),
    (10, messages.LogRequest(first_sample=5_000, end_sample=5_100)),
    (10, messages.ParamGet(index=0)),
    (1_000, messages.Pause()),
    (1_000, messages.Hover(depth_m=1.0)),
    (1_000, messages.StartLearning(max_episodes=3)),
    (6_000, messages.Stop()),
    (1_500, messages.StartLearning(max_episodes=0)),
    (2_000, messages.Surface()),
    (1_000, messages.Timesync(origin_us=99)),
)


@dataclass
class Trace:
    wire: bytearray = field(default_factory=bytearray)
    frames: int = 0

    def write(self, data: bytes) -> None:
        self.wire += data
        self.frames += 1


def build(preset_name: str, seed: int, trace: Trace) -> tuple[AgentLink, OnboardProgram]:
    """The link and program of `AgentServer` for this seed, writing into `trace`; boot_id fixed (it is random)."""
    params = preset(preset_name)
    rng = np.random.default_rng(seed)
    link = AgentLink(trace.write, node_id=0x5100_0000 | (seed & 0xFFFF))
    link.boot_id = 0x1234_5678
    program = OnboardProgram(params, learner_preset("paper"), MissionConfig(), SimulatedHardware(params, rng), rng,
                             link)
    link.attach(program)
    return link, program


def in_process_agent(key: bytes | None = None) -> tuple[AgentLink, OnboardProgram, bytearray]:
    """The hardware preset's agent with the default learner, connected, its link writing into the bytearray
    returned (a 64 KiB log): for feeding its receive path frames in-process; signing with `key` if given."""
    out = bytearray()
    link = AgentLink(out.extend, node_id=1, ring=LogRing(64 * 1024), key=key)
    params = preset("hardware")
    rng = np.random.default_rng(0)
    program = OnboardProgram(params, LearnerConfig(), MissionConfig(), SimulatedHardware(params, rng), rng, link)
    link.attach(program)
    link.on_connect()
    return link, program, out


def step_by_step(link: AgentLink, program: OnboardProgram, steps: int) -> None:
    """How the server ran the program before batches: one step and one link tick per call."""
    for _ in range(steps):
        program.step()
        link.tick()


def run(preset_name: str = "hardware", seed: int = 1,
        advance: Callable[[AgentLink, OnboardProgram, int], None] = step_by_step) -> dict[str, object]:
    trace = Trace()
    link, program = build(preset_name, seed, trace)
    link.on_connect()
    ground = FrameEncoder(first_seq=700)
    for steps, message in SCRIPT:
        advance(link, program, steps)
        link.receive(ground.encode(message).wire)
    advance(link, program, 500)
    log = b"".join(len(r.inner).to_bytes(1, "little") + r.inner for r in link.ring.records(0, 2**32 - 1))
    return {
        "preset": preset_name, "seed": seed, "wire_bytes": len(trace.wire), "frames": trace.frames,
        "wire_sha256": hashlib.sha256(trace.wire).hexdigest(), "log_records": len(link.ring),
        "log_sha256": hashlib.sha256(log).hexdigest(), "t_us": program.t_us, "next_sample": program.next_sample,
        "episodes": program.learner.episode,
    }


if __name__ == "__main__":
    print(json.dumps([run("hardware", 1), run("paper", 2)], indent=1))
