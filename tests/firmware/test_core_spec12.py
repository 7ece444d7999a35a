"""SPEC.md 1.2 on the C agent's host build: a ground HELLO empties the ACK memory, setting the current value of a
learner parameter restarts nothing, a refused CMD_DUMP takes no snapshot."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from protocol import AckResult, FrameEncoder, FrameFlag, NodeKind, StreamDecoder, definitions_hash, messages
from simulator.parameters import preset
from tests.firmware.core_build import use_firmware_cache

ACK = int(FrameFlag.ACK_REQUESTED)


class Agent:
    def __init__(self) -> None:
        from simulator.serve.firmware_host import FirmwareAgent

        self.decoder = StreamDecoder()
        self.frames: list[Any] = []
        self.agent = FirmwareAgent(preset("hardware"), np.random.default_rng(3), self.frames_in, node_id=9, key=None,
                                   seed=3)

    def frames_in(self, wire: bytes) -> None:
        self.frames += self.decoder.feed(wire)

    def send(self, wire: bytes) -> list[Any]:
        self.frames.clear()
        self.agent.receive(wire)
        for _ in range(50):  # replies are sent in slices by the firmware's poll
            self.agent.service()
        return [f.message for f in self.frames]


@pytest.fixture
def fw(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Agent]:
    use_firmware_cache(tmp_path_factory)
    yield Agent()


def _acks(out: list[Any]) -> list[AckResult]:
    return [AckResult(m.result) for m in out if isinstance(m, messages.Ack)]


def test_a_ground_hello_empties_the_ack_memory(fw: Agent) -> None:
    ground = FrameEncoder(first_seq=10)
    get = ground.encode(messages.ParamGet(index=3, name=""), ACK).wire
    assert _acks(fw.send(get)) == [AckResult.ACCEPTED]
    again = fw.send(get)  # remembered: the ACK again, not executed
    assert _acks(again) == [AckResult.ACCEPTED] and not [m for m in again if isinstance(m, messages.ParamValue)]
    hello = messages.Hello(protocol_version=1, node_kind=int(NodeKind.GROUND), definitions_hash=definitions_hash(),
                           node_id=7, boot_id=1)
    fw.send(ground.encode(hello).wire)
    after = fw.send(get)  # a new session: the same (msg_id, seq) is executed
    assert _acks(after) == [AckResult.ACCEPTED] and [m for m in after if isinstance(m, messages.ParamValue)]


def test_the_current_value_restarts_nothing_and_a_refused_dump_takes_no_id(fw: Agent) -> None:
    ground = FrameEncoder(first_seq=100)
    out = fw.send(ground.encode(messages.ParamGet(index=-1, name="gamma"), ACK).wire)
    gamma = next(m for m in out if isinstance(m, messages.ParamValue)).value
    out = fw.send(ground.encode(messages.ParamSet(index=-1, value=gamma, name="gamma"), ACK).wire)
    assert _acks(out) == [AckResult.ACCEPTED]
    assert not [m for m in out if isinstance(m, messages.Text) and "restarted" in m.text]
    out = fw.send(ground.encode(messages.DumpRequest(kind=2, dump_id=0, offset=0, length=0), ACK).wire)
    first_id = next(m for m in out if isinstance(m, messages.DumpChunk)).dump_id
    out = fw.send(ground.encode(messages.DumpRequest(kind=2, dump_id=0, offset=10**6, length=0), ACK).wire)
    assert _acks(out) == [AckResult.BAD_VALUE]
    out = fw.send(ground.encode(messages.DumpRequest(kind=2, dump_id=0, offset=0, length=0), ACK).wire)
    assert next(m for m in out if isinstance(m, messages.DumpChunk)).dump_id == first_id + 1
    out = fw.send(ground.encode(messages.ParamSet(index=-1, value=0.95, name="gamma"), ACK).wire)
    assert [m for m in out if isinstance(m, messages.Text) and "restarted" in m.text]
