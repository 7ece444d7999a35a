"""The C agent's on-board log over a small EEPROM (wrapped many times): LOG_REQUEST replays exactly the samples
asked for that are still held, in order, flagged REPLAYED, at most 512 SAMPLEs per request, then LOG_RANGE."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from protocol import AckResult, FrameFlag, StreamDecoder, messages
from protocol.cobs import cobs_encode
from protocol.frame import build_inner
from simulator.parameters import preset
from tests.firmware.core_build import use_firmware_cache

CAPACITY_BYTES = 40_000  # ~700 records: ~40 s of hovering at 40 Hz wraps it several times


class LoggingAgent:
    def __init__(self) -> None:
        from simulator.serve.firmware_host import FirmwareAgent

        self.decoder = StreamDecoder()
        self.frames: list[Any] = []
        self.agent = FirmwareAgent(preset("hardware"), np.random.default_rng(3), self._write, node_id=3, key=None,
                                   seed=3, log_capacity_bytes=CAPACITY_BYTES)
        self.seq = 1

    def _write(self, wire: bytes) -> None:
        self.frames += self.decoder.feed(wire)

    def command(self, message: Any) -> None:
        self.agent.receive(cobs_encode(build_inner(int(FrameFlag.ACK_REQUESTED), self.seq, message.MSG_ID,
                                                   message.pack())) + b"\0")
        self.seq += 1

    def replay(self, first: int, end: int) -> tuple[list[Any], messages.LogRange]:
        self.frames.clear()
        self.command(messages.LogRequest(first_sample=first, end_sample=end))
        for _ in range(400):
            if any(isinstance(f.message, messages.LogRange) for f in self.frames):
                break
            self.agent.step()
        acks = [f.message for f in self.frames if isinstance(f.message, messages.Ack)]
        assert [a.result for a in acks] == [AckResult.ACCEPTED]
        ranges = [f.message for f in self.frames if isinstance(f.message, messages.LogRange)]
        assert len(ranges) == 1
        return [f for f in self.frames if f.flags & FrameFlag.REPLAYED], ranges[0]


@pytest.fixture(scope="module")
def agent(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LoggingAgent]:
    use_firmware_cache(tmp_path_factory)
    a = LoggingAgent()
    a.command(messages.Hover(depth_m=0.3))  # SAMPLE every 25 ms
    for _ in range(3000):
        a.agent.step()
    yield a


def test_wrapped_log_replays_what_it_holds(agent: LoggingAgent) -> None:
    replayed, ranges = agent.replay(0, 0xFFFFFFFF)
    assert ranges.capacity_bytes == CAPACITY_BYTES and ranges.bytes_used <= CAPACITY_BYTES
    assert ranges.first_sample > 1000  # the first samples are long overwritten
    samples = [f.message.sample for f in replayed if isinstance(f.message, messages.Sample)]
    # The oldest held sample first (LOG_RANGE, sent after the replay, already reports a later oldest one: the
    # agent kept logging while it replayed), in order, and no more than 512 (the log holds ~700).
    assert samples == list(range(samples[0], samples[0] + 512)) and 1000 < samples[0] <= ranges.first_sample
    assert ranges.replayed == len(replayed)


def test_a_window_from_the_middle(agent: LoggingAgent) -> None:
    _, before = agent.replay(0, 0)  # end <= first: nothing replayed, only LOG_RANGE
    assert before.replayed == 0
    first = (before.first_sample // 256 + 1) * 256 + 7  # just past a checkpoint of the index
    replayed, ranges = agent.replay(first, first + 40)
    samples = [f.message.sample for f in replayed if isinstance(f.message, messages.Sample)]
    assert samples == list(range(first, first + 40))
    assert all(f.message.mode == 3 for f in replayed)  # logged while hovering, sent with their own payload
