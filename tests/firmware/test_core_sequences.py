"""The C agent (host build, in process) fed the ground's frames of tests/vectors/sequences.jsonl byte for byte: its
answers follow the rules those examples show (tests/protocol/sequence_rules.py, as the virtual agent's do), and
where SPEC.md fixes an answer (ACK, PARAM_VALUE, LOG_RANGE, the SAMPLE indices and modes of a session's start and a
reconnect) it is the vector's, payload for payload."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from protocol import FrameFlag, Mode, StreamDecoder
from simulator.parameters import preset
from tests.firmware.core_build import use_firmware_cache
from tests.protocol.sequence_rules import (
    Frames,
    check_episode_order,
    check_learner_restart,
    check_reused_seq_is_executed,
    check_session_start,
    shown,
)
from tests.vectors.generate_sequences import SEQUENCES_PATH, elide, entry

EXAMPLES = [json.loads(line) for line in SEQUENCES_PATH.read_text(encoding="utf-8").splitlines()]
FIXED = ("ACK", "PARAM_VALUE", "LOG_RANGE")  # answers SPEC.md fixes field for field, whoever the agent is
HELLO_FIXED = ("protocol_version", "node_kind", "definitions_hash")  # the rest of a HELLO is the agent's own


class CRecorder:
    """The C agent and every frame both ways, as tests/vectors/generate_sequences.Recorder records the virtual one."""

    def __init__(self) -> None:
        from simulator.serve.firmware_host import FirmwareAgent

        self.frames: Frames = []
        self.replayed: list[int] = []  # the SAMPLE indices sent with the REPLAYED flag
        self.connected = True
        self.mode = Mode.IDLE  # from its SAMPLEs and HEARTBEATs, as a ground knows it
        self._decoder = StreamDecoder()
        self.agent = FirmwareAgent(preset("paper"), np.random.default_rng(7), self._wrote, node_id=0x51000007,
                                   key=None, seed=7)

    def _wrote(self, wire: bytes) -> None:
        for frame in self._decoder.feed(wire):  # FirmwareAgent writes one frame per call
            if frame.message.DEFINITION.name in ("SAMPLE", "HEARTBEAT"):
                self.mode = Mode(frame.message.mode)
            if self.connected:
                self.frames.append(entry("a", frame.message, wire))
                if frame.flags & FrameFlag.REPLAYED:
                    self.replayed.append(frame.message.sample)

    def send(self, frame: dict[str, Any]) -> None:
        """A ground frame of the vector, its bytes as they are there."""
        self.frames.append(frame)
        self.agent.receive(bytes.fromhex(frame["wire_hex"]))

    def steps(self, count: int) -> None:
        for _ in range(count):
            self.agent.step()

    def until(self, done: Callable[[], bool], most: int = 20_000) -> None:
        for _ in range(most):
            if done():
                return
            self.agent.step()
        raise AssertionError(f"the C agent is {self.mode.name} after {most} steps")

    def take(self) -> Frames:
        frames, self.frames = self.frames, []
        return frames


def _ground(example: dict[str, Any]) -> Frames:
    return [f for f in shown(example["frames"]) if f["dir"] == "g"]


@pytest.fixture(scope="module")
def answers(tmp_path_factory: pytest.TempPathFactory) -> tuple[list[Frames], list[int]]:
    """The C agent's run through the four examples (the script of tests/vectors/generate_sequences.sequences)."""
    use_firmware_cache(tmp_path_factory)
    r = CRecorder()
    r.take()  # its HELLO at power-up, before any link
    session_g, reconnect_g, episode_g, restart_g = (_ground(e) for e in EXAMPLES)
    r.agent.link_up()
    for frame in session_g:
        r.send(frame)
    r.steps(12)
    session = r.take()
    r.connected = False  # the link drops for 3 s: what it sends meanwhile is lost (and logged)
    r.steps(30)
    r.connected = True
    r.agent.link_up()
    for frame in reconnect_g:
        r.send(frame)
    reconnect = r.take()
    start_one, start_again, stop = episode_g
    r.send(start_one)  # CMD_START max_episodes 1: one episode, its natural end, back at the surface
    r.until(lambda: r.mode == Mode.SURFACING)
    r.until(lambda: r.mode == Mode.IDLE)
    r.steps(1)
    r.send(start_again)
    r.until(lambda: r.mode == Mode.LEARNING)
    r.steps(3)
    r.send(stop)
    r.steps(1)
    episode = elide(r.take())
    r.until(lambda: r.mode == Mode.IDLE)
    r.take()
    reset, start, stop = restart_g  # 1.3: CMD_RESET_MODEL, then an episode of the new learner, stopped
    r.send(reset)
    r.until(lambda: any(f.get("msg") == "HEARTBEAT" for f in r.frames))
    r.send(start)
    r.until(lambda: r.mode == Mode.LEARNING)
    r.steps(3)
    r.send(stop)
    r.steps(1)
    return [session, reconnect, episode, elide(r.take())], r.replayed


def _kinds(frames: Frames) -> list[tuple[str, str]]:
    return [(f["dir"], f["msg"]) for f in shown(frames)]


def test_the_c_agent_follows_the_session_and_reconnect_rules(answers: tuple[list[Frames], list[int]]) -> None:
    (session, reconnect, *_), _ = answers
    check_session_start(session)
    check_session_start(reconnect)
    check_reused_seq_is_executed(session, reconnect)


def test_the_c_agent_follows_the_episode_rules(answers: tuple[list[Frames], list[int]]) -> None:
    check_episode_order(answers[0][2])


def test_the_c_agent_numbers_a_new_generation_after_a_learner_restart(
        answers: tuple[list[Frames], list[int]]) -> None:
    check_learner_restart(answers[0][3])


@pytest.mark.parametrize("index", [0, 1], ids=["session start", "reconnect"])
def test_where_the_sequence_is_fixed_the_c_agent_answers_as_the_vector(
        answers: tuple[list[Frames], list[int]], index: int) -> None:
    """A session's start and a reconnect are deterministic: the same frames in the same order; the ground's are the
    vector's bytes; ACK, PARAM_VALUE and LOG_RANGE payloads are the vector's byte for byte; SAMPLEs have its indices,
    episodes and modes; the missed SAMPLEs come back REPLAYED."""
    mine, vector = answers[0][index], EXAMPLES[index]["frames"]
    assert _kinds(mine) == _kinds(vector)
    for got, want in zip(shown(mine), shown(vector), strict=True):
        if got["dir"] == "g":
            assert got["wire_hex"] == want["wire_hex"]
        elif got["msg"] in FIXED:
            assert _payload(got) == _payload(want), (got["fields"], want["fields"])
        elif got["msg"] == "HELLO":
            assert [got["fields"][k] for k in HELLO_FIXED] == [want["fields"][k] for k in HELLO_FIXED]
        elif got["msg"] == "SAMPLE":
            keys = ("sample", "episode", "step", "mode")
            assert [got["fields"][k] for k in keys] == [want["fields"][k] for k in keys]
    if index == 1:
        asked = next(f["fields"] for f in vector if f["msg"] == "LOG_REQUEST")
        assert answers[1] == list(range(asked["first_sample"], asked["end_sample"]))


def _payload(frame: dict[str, Any]) -> bytes:
    """The message's bytes (not the frame's seq and CRC, which count the agent's own frames)."""
    (decoded,) = StreamDecoder().feed(bytes.fromhex(frame["wire_hex"]))
    return bytes(decoded.message.pack())
