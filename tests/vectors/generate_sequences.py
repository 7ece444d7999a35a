"""Writes tests/vectors/sequences.jsonl, SPEC.md's examples byte-exact: `python -m tests.vectors.generate_sequences`.

Each line is one example: `name` and `frames`, in the order they crossed the link, each `dir` ("g" ground to agent,
"a" agent to ground), `msg` (the message name), `wire_hex` (COBS-encoded with its delimiter) and `fields`; a run of
SAMPLEs in the middle of an episode is left out as one `{"elided": N}`. The agent is the virtual agent (seeded, its
boot_id fixed), so its bytes are reproducible; another agent's `t_us`, depths and states differ, but the order,
the message kinds and the fields SPEC.md fixes (modes, `episode`, `sample`, `reason`, `action` 255 on the ending
step, ACK results, `generation`) are what every 1.3 agent sends.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from learning import LearnerConfig
from protocol import FrameEncoder, FrameFlag, Mode, NodeKind, StreamDecoder, definitions_hash, messages
from protocol.registry import Message
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import PythonAgent
from simulator.parameters import preset

SEQUENCES_PATH = Path(__file__).with_name("sequences.jsonl")
ACK = int(FrameFlag.ACK_REQUESTED)
SEED = 7
BOOT_ID = 0x0B007ED1
KEEP_SAMPLES = 2  # SAMPLEs kept at each end of a run of LEARNING SAMPLEs
GROUND_HELLO = messages.Hello(protocol_version=1, node_kind=int(NodeKind.GROUND), definitions_hash=definitions_hash(),
                              node_id=7, boot_id=1)


class Recorder:
    """The virtual agent in memory and every frame both ways, in order."""

    def __init__(self) -> None:
        self.frames: list[dict[str, Any]] = []
        self.connected = True
        self._decoder = StreamDecoder()
        self.agent = PythonAgent(preset("paper"), LearnerConfig(), MissionConfig(), np.random.default_rng(SEED),
                                 self._agent_wrote, node_id=0x51000007, key=None)
        self.agent.link.boot_id = BOOT_ID
        self.ground = FrameEncoder(first_seq=1)

    def _agent_wrote(self, wire: bytes) -> None:
        if not self.connected:
            return  # produced (logged, seq used), lost with the link
        start = 0
        for frame in self._decoder.feed(wire):
            end = wire.index(b"\x00", start) + 1
            self.frames.append(entry("a", frame.message, wire[start:end]))
            start = end

    def send(self, message: Message, *, seq: int | None = None, flush: bool = False) -> int:
        encoded = (FrameEncoder(first_seq=seq) if seq is not None else self.ground).encode(
            message, ACK if message.MSG_ID >= 0x80 else 0)
        wire = (b"\x00" if flush else b"") + encoded.wire
        self.frames.append(entry("g", message, wire))
        self.agent.receive(wire)
        return encoded.seq

    def steps(self, count: int) -> None:
        for _ in range(count):
            self.agent.step()

    def until(self, done: Any, most: int = 200_000) -> None:
        for _ in range(most):
            if done():
                return
            self.agent.step()
        raise RuntimeError("the example did not reach its end")

    def mode(self) -> Mode:
        return self.agent.program.mode


def entry(direction: str, message: Message, wire: bytes) -> dict[str, Any]:
    return {"dir": direction, "msg": message.DEFINITION.name, "wire_hex": wire.hex(), "fields": message.to_dict()}


def elide(frames: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Runs of LEARNING SAMPLEs cut to their first and last KEEP_SAMPLES, the middle as {"elided": N}."""
    out: list[dict[str, Any]] = []
    run: list[dict[str, Any]] = []

    def close() -> None:
        if len(run) > 2 * KEEP_SAMPLES + 1:
            out.extend([*run[:KEEP_SAMPLES], {"elided": len(run) - 2 * KEEP_SAMPLES}, *run[-KEEP_SAMPLES:]])
        else:
            out.extend(run)
        run.clear()

    for f in frames:
        learning_sample = f.get("msg") == "SAMPLE" and f["fields"]["mode"] == int(Mode.LEARNING)
        if learning_sample:
            run.append(f)
        else:
            close()
            out.append(f)
    close()
    return out


def sequences() -> list[dict[str, Any]]:
    r = Recorder()
    # A session's start: the agent's HELLO on the new link, the ground's flush and HELLO, the answer, a command.
    r.agent.link_up()
    r.send(GROUND_HELLO, flush=True)
    reused = r.send(messages.ParamGet(index=19, name=""))
    r.steps(12)  # 1.2 s of IDLE: a SAMPLE and a HEARTBEAT
    session = list(r.frames)
    # A reconnect: the link drops for 3 s (frames produced meanwhile are logged and lost), the ground comes back
    # with the same seq counter start, its first command reusing a seq of the last session: executed, not answered
    # from the ACK memory; it asks for the SAMPLEs it missed.
    r.frames.clear()
    missed_from = r.agent.program.next_sample
    r.agent.link_down()
    r.connected = False
    r.steps(30)
    r.connected = True
    r.agent.link_up()
    r.send(GROUND_HELLO, flush=True)
    r.send(messages.ParamGet(index=19, name=""), seq=reused)
    r.send(messages.LogRequest(first_sample=missed_from, end_sample=r.agent.program.next_sample))
    reconnect = list(r.frames)
    # An episode's start and natural end (the paper preset starts it at rest), then an abort by CMD_STOP.
    r.frames.clear()
    r.send(messages.StartLearning(max_episodes=1))
    r.until(lambda: r.mode() == Mode.SURFACING)
    r.until(lambda: r.mode() == Mode.IDLE)
    r.steps(1)
    r.send(messages.StartLearning(max_episodes=0))
    r.until(lambda: r.mode() == Mode.LEARNING)
    r.steps(3)
    r.send(messages.Stop())
    r.steps(1)
    episode = elide(list(r.frames))
    # A learner restart (1.3): CMD_RESET_MODEL in IDLE; the next HEARTBEAT and episode carry generation 2, the
    # episode numbered 1 again.
    r.until(lambda: r.mode() == Mode.IDLE)
    r.frames.clear()
    r.send(messages.ResetModel())
    r.until(lambda: any(f.get("msg") == "HEARTBEAT" for f in r.frames))
    r.send(messages.StartLearning(max_episodes=0))
    r.until(lambda: r.mode() == Mode.LEARNING)
    r.steps(3)
    r.send(messages.Stop())
    r.steps(1)
    restart = elide(list(r.frames))
    return [
        {"name": "a session's start (SPEC.md 4, sessions)", "frames": session},
        {"name": "a reconnect: ACK memory emptied, the missed SAMPLEs replayed (SPEC.md 4, 5, 7)",
         "frames": reconnect},
        {"name": "an episode's start and end, then one aborted by CMD_STOP (SPEC.md 6, episodes)", "frames": episode},
        {"name": "a learner restart: a new generation, episodes from 1 again (SPEC.md 6, learner generations)",
         "frames": restart},
    ]


def render() -> str:
    return "".join(json.dumps(s, ensure_ascii=False) + "\n" for s in sequences())


if __name__ == "__main__":
    SEQUENCES_PATH.write_text(render(), encoding="utf-8")
    print(f"wrote {SEQUENCES_PATH}")
