"""The C agent (host build, in process) against tests/vectors/receive.jsonl: what it counts and which ACKs it
sends for given bytes (SPEC.md 1.1 sections 1, 4, 5), then the ACK memory and command x mode rules."""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from protocol import AckResult, FrameFlag, Mode, StreamDecoder, messages
from protocol.cobs import cobs_encode
from protocol.frame import build_inner
from simulator.parameters import preset
from tests.firmware.core_build import ROOT, use_firmware_cache

VECTORS = ROOT / "tests" / "vectors" / "receive.jsonl"


class Agent:
    """A FirmwareAgent whose frames are decoded as a ground station would."""

    def __init__(self) -> None:
        from simulator.serve.firmware_host import FirmwareAgent

        self.decoder = StreamDecoder()
        self.frames: list[Any] = []
        self.agent = FirmwareAgent(preset("hardware"), np.random.default_rng(1), self._write, node_id=7, key=None,
                                   seed=1)
        self.seq = 1

    def _write(self, wire: bytes) -> None:
        self.frames += self.decoder.feed(wire)

    def take(self) -> list[Any]:
        frames, self.frames = self.frames, []
        return frames

    def acks(self) -> list[messages.Ack]:
        return [f.message for f in self.take() if isinstance(f.message, messages.Ack)]

    def command(self, message: Any, seq: int | None = None) -> list[Any]:
        """Send a command frame (ACK_REQUESTED) and return what came back."""
        if seq is None:
            seq = self.seq
            self.seq += 1
        inner = build_inner(int(FrameFlag.ACK_REQUESTED), seq, message.MSG_ID, message.pack())
        self.agent.receive(cobs_encode(inner) + b"\0")
        return self.take()

    def mode(self) -> Mode:
        """The mode the next SAMPLE reports (stepping until one comes)."""
        for _ in range(40):
            self.agent.step()
            samples = [f.message for f in self.take() if isinstance(f.message, messages.Sample)]
            if samples:
                return Mode(samples[-1].mode)
        raise AssertionError("no SAMPLE in 40 steps")


@pytest.fixture(scope="module")
def agent(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Agent]:
    use_firmware_cache(tmp_path_factory)
    yield Agent()


@pytest.mark.parametrize("vector", [json.loads(line) for line in VECTORS.read_text().splitlines() if line.strip()],
                         ids=lambda v: v["name"][:50])
def test_receive_vector(agent: Agent, vector: dict[str, Any]) -> None:
    agent.agent.link_up()  # a new link: sequence tracking starts over
    agent.take()
    before = agent.agent.counters()
    agent.agent.receive(bytes.fromhex(vector["wire_hex"]))
    after = agent.agent.counters()
    delta = {k: after[k] - before[k] for k in ("rx_frames", "rx_rejects", "rx_lost")}
    assert delta == {k: vector[k] for k in ("rx_frames", "rx_rejects", "rx_lost")}
    assert [AckResult(a.result).name for a in agent.acks()] == vector["ack"]
    while agent.mode() != Mode.IDLE:  # an executed CMD_SURFACE: back at the surface for the next vector
        pass


def test_ack_memory_answers_a_retry_without_acting_again(agent: Agent) -> None:
    first = agent.command(messages.Hover(depth_m=0.3), seq=40000)
    assert [f.message.result for f in first if isinstance(f.message, messages.Ack)] == [AckResult.ACCEPTED]
    assert any(isinstance(f.message, messages.Text) for f in first)  # the mode change it caused
    retry = agent.command(messages.Hover(depth_m=0.3), seq=40000)
    acks = [f.message for f in retry if isinstance(f.message, messages.Ack)]
    assert [(a.cmd_seq, a.result, a.reason) for a in acks] == [(40000, AckResult.ACCEPTED, "")]
    assert not any(isinstance(f.message, messages.Text) for f in retry)  # not executed again


def test_command_matrix_and_value_checks(agent: Agent) -> None:
    def result(message: Any) -> AckResult:
        acks = [f.message for f in agent.command(message) if isinstance(f.message, messages.Ack)]
        assert len(acks) == 1
        return AckResult(acks[0].result)

    assert result(messages.Hover(depth_m=float("nan"))) == AckResult.BAD_VALUE
    assert result(messages.Hover(depth_m=3.0)) == AckResult.BAD_VALUE
    assert result(messages.Surface()) == AckResult.ACCEPTED
    assert result(messages.Surface()) == AckResult.ACCEPTED  # stays SURFACING
    assert result(messages.Pause()) == AckResult.NOT_ALLOWED_IN_MODE
    assert result(messages.Hover(depth_m=0.5)) == AckResult.NOT_ALLOWED_IN_MODE
    assert result(messages.DumpRequest(kind=9)) == AckResult.BAD_VALUE
    assert result(messages.DumpRequest(kind=1, dump_id=12345)) == AckResult.STALE


def test_param_set_refusals_send_no_param_value(agent: Agent) -> None:
    def answer(**fields: Any) -> tuple[AckResult, list[messages.ParamValue]]:
        frames = agent.command(messages.ParamSet(**fields))
        acks = [f.message for f in frames if isinstance(f.message, messages.Ack)]
        return AckResult(acks[0].result), [f.message for f in frames if isinstance(f.message, messages.ParamValue)]

    assert answer(index=-1, name="z_cells", value=10.5) == (AckResult.BAD_VALUE, [])
    assert answer(index=-1, name="z_cells", value=float("inf")) == (AckResult.BAD_VALUE, [])
    assert answer(index=-1, name="gamma", value=1.5) == (AckResult.BAD_VALUE, [])
    assert answer(index=99, value=1.0) == (AckResult.BAD_VALUE, [])
    assert answer(index=-1, name="no_such_parameter", value=1.0) == (AckResult.BAD_VALUE, [])
    # 50 x 50 x 9 + 1 = 22 501 states: refused, the reason names the bytes.
    frames = agent.command(messages.ParamSet(index=-1, name="act_bins", value=9.0))
    agent.command(messages.ParamSet(index=-1, name="z_cells", value=50.0))
    frames = agent.command(messages.ParamSet(index=-1, name="zdot_cells", value=50.0))
    ack = next(f.message for f in frames if isinstance(f.message, messages.Ack))
    assert ack.result == AckResult.BAD_VALUE and " B" in ack.reason
    result, values = answer(index=-1, name="target_depth_m", value=0.5)
    assert result == AckResult.ACCEPTED and len(values) == 1
    assert values[0].value == struct.unpack("<f", struct.pack("<f", 0.5))[0]
    result, values = answer(index=-1, name="gamma", value=0.95)
    assert values[0].value == struct.unpack("<f", struct.pack("<f", 0.95))[0]  # the stored f32, widened exactly
    for name, value in (("act_bins", 1.0), ("z_cells", 10.0), ("gamma", 0.99)):
        assert answer(index=-1, name=name, value=value)[0] == AckResult.ACCEPTED


def test_log_request_replays_with_the_replayed_flag(agent: Agent) -> None:
    for _ in range(30):
        agent.agent.step()
    agent.take()
    frames = agent.command(messages.LogRequest(first_sample=0, end_sample=0xFFFFFFFF))
    for _ in range(60):  # replies are streamed a few per poll
        agent.agent.step()
        frames += agent.take()
        if any(isinstance(f.message, messages.LogRange) for f in frames):
            break
    replayed = [f for f in frames if f.flags & FrameFlag.REPLAYED]
    ranges = [f.message for f in frames if isinstance(f.message, messages.LogRange)]
    assert len(ranges) == 1 and ranges[0].replayed == len(replayed) > 0
    assert sum(isinstance(f.message, messages.Sample) for f in replayed) <= 512
    assert ranges[0].capacity_bytes == 512 * 1024


def test_dump_values_in_224_byte_chunks(agent: Agent) -> None:
    frames = agent.command(messages.DumpRequest(kind=3))  # Q values: 8 S bytes
    for _ in range(5):
        agent.agent.step()
        frames += agent.take()
    chunks = [f.message for f in frames if isinstance(f.message, messages.DumpChunk)]
    total = chunks[0].total_bytes
    assert total == 8 * 101 and all(len(c.data) <= 224 for c in chunks)
    assert b"".join(c.data for c in chunks) and sum(len(c.data) for c in chunks) == total
    again = agent.command(messages.DumpRequest(kind=3, dump_id=chunks[0].dump_id, offset=224, length=10))
    for _ in range(3):
        agent.agent.step()
        again += agent.take()
    resent = [f.message for f in again if isinstance(f.message, messages.DumpChunk)]
    assert [(c.offset, len(c.data)) for c in resent] == [(224, 10)]
    at_end = agent.command(messages.DumpRequest(kind=3, dump_id=chunks[0].dump_id, offset=total))
    assert [f.message.result for f in at_end if isinstance(f.message, messages.Ack)] == [AckResult.ACCEPTED]


def test_stop_in_learning_acks_then_aborts_the_episode(agent: Agent) -> None:
    """The LEARNING cell of CMD_STOP and CMD_PAUSE: ACK first, then EPISODE_END aborted, then the new mode."""
    for command, mode in ((messages.Stop(), Mode.SURFACING), (messages.Pause(), Mode.PAUSED)):
        while agent.mode() != Mode.IDLE:
            pass
        agent.command(messages.StartLearning(max_episodes=0))
        started = False
        for _ in range(20_000):  # recovery to the start depth, then the settle time: ~40 s of agent time
            agent.agent.step()
            if any(isinstance(f.message, messages.EpisodeStart) for f in agent.take()):
                started = True
                break
        assert started, "no episode began"
        frames = agent.command(command)
        kinds = [type(f.message).__name__ for f in frames if not isinstance(f.message, messages.Text)]
        assert kinds[:2] == ["Ack", "EpisodeEnd"], kinds
        assert frames[0].message.result == AckResult.ACCEPTED
        end = next(f.message for f in frames if isinstance(f.message, messages.EpisodeEnd))
        assert end.reason == 3  # aborted
        assert agent.mode() == mode
        agent.command(messages.Surface())
