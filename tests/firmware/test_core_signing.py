"""Signing on the C agent (SPEC.md 1.1 s. 12): the order of checks, replay, too new, CMD_SURFACE always runs,
the mark persisted through hal_nv_* refuses what was accepted before a reboot."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from protocol import AckResult, FrameEncoder, FrameFlag, StreamDecoder, messages
from protocol.signing import Signer
from simulator.parameters import preset
from tests.firmware.core_build import use_firmware_cache

KEY = bytes(range(32))
ACK = int(FrameFlag.ACK_REQUESTED)


class Clock:
    """The ground's wall clock, moved by hand."""

    def __init__(self) -> None:
        self.ns = time.time_ns()

    def __call__(self) -> int:
        return self.ns


class KeyedAgent:
    def __init__(self) -> None:
        from simulator.serve.firmware_host import FirmwareAgent

        self.decoder = StreamDecoder()
        self.frames: list[Any] = []
        self.agent = FirmwareAgent(preset("hardware"), np.random.default_rng(2), self.frames_in, node_id=9, key=KEY,
                                   seed=2)

    def frames_in(self, wire: bytes) -> None:
        self.frames += self.decoder.feed(wire)

    def send(self, wire: bytes) -> list[messages.Ack]:
        self.frames.clear()
        self.agent.receive(wire)
        return [f.message for f in self.frames if isinstance(f.message, messages.Ack)]

    def texts(self) -> int:
        return sum(isinstance(f.message, messages.Text) for f in self.frames)


@pytest.fixture
def keyed(tmp_path_factory: pytest.TempPathFactory) -> Iterator[KeyedAgent]:
    use_firmware_cache(tmp_path_factory)
    yield KeyedAgent()


def results(acks: list[messages.Ack]) -> list[AckResult]:
    return [AckResult(a.result) for a in acks]


def test_unsigned_and_wrongly_signed_commands_are_refused(keyed: KeyedAgent) -> None:
    plain = FrameEncoder(first_seq=10)
    assert results(keyed.send(plain.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.UNAUTHORIZED]
    wrong = FrameEncoder(first_seq=20, signer=Signer(bytes(32), 3))
    assert results(keyed.send(wrong.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.UNAUTHORIZED]
    assert keyed.agent.counters()["signing_rejects"] == 2


def test_exact_replay_gets_the_original_ack_and_is_not_run_again(keyed: KeyedAgent) -> None:
    clock = Clock()
    ground = FrameEncoder(first_seq=100, signer=Signer(KEY, 5, clock))
    wire = ground.encode(messages.Hover(depth_m=0.2), ACK).wire
    assert results(keyed.send(wire)) == [AckResult.ACCEPTED] and keyed.texts() == 1
    assert results(keyed.send(wire)) == [AckResult.ACCEPTED] and keyed.texts() == 0  # ACK memory first
    # The same timestamp on a new command (new seq) is a replay.
    clock.ns -= 10**9
    older = FrameEncoder(first_seq=200, signer=Signer(KEY, 5, clock))
    assert results(keyed.send(older.encode(messages.Hover(depth_m=0.3), ACK).wire)) == [AckResult.UNAUTHORIZED]


def test_too_new_refused_but_surface_always_runs(keyed: KeyedAgent) -> None:
    clock = Clock()
    ground = FrameEncoder(first_seq=300, signer=Signer(KEY, 6, clock))
    assert results(keyed.send(ground.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.ACCEPTED]
    clock.ns += 120 * 10**9  # two minutes ahead of the agent's estimate
    assert results(keyed.send(ground.encode(messages.Hover(depth_m=0.4), ACK).wire)) == [AckResult.UNAUTHORIZED]
    assert results(keyed.send(ground.encode(messages.Surface(), ACK).wire)) == [AckResult.ACCEPTED]
    assert keyed.texts() == 1  # HOVER -> SURFACING


def test_mark_survives_a_reboot(keyed: KeyedAgent) -> None:
    clock = Clock()
    ground = FrameEncoder(first_seq=400, signer=Signer(KEY, 7, clock))
    recorded = ground.encode(messages.Hover(depth_m=0.2), ACK).wire
    assert results(keyed.send(recorded)) == [AckResult.ACCEPTED]
    io = keyed.agent._io
    assert io.nv_writes >= 1 and io.nv_len > 0
    keyed.agent._lib.host_init(9, KEY)  # reboot: RAM state gone, the nv area kept
    keyed.frames.clear()
    assert results(keyed.send(recorded)) == [AckResult.UNAUTHORIZED]  # recorded before the reboot
    clock.ns += 11 * 10**9  # past the persisted mark (accepted + 10 s)
    fresh = FrameEncoder(first_seq=500, signer=Signer(KEY, 8, clock))
    assert results(keyed.send(fresh.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.ACCEPTED]


def test_a_re_sync_lowers_the_mark_a_clock_an_hour_ahead_left_so_a_reboot_does_not_lock_out_again(
        keyed: KeyedAgent) -> None:
    """SPEC.md s. 12, "Re-sync" (issue 25 L5): the mark an hour ahead is replaced by the re-sync's, in nv."""
    from protocol.signing import RESYNC_NAME, resync_nonce

    ahead = FrameEncoder(first_seq=1000, signer=Signer(KEY, 11, lambda: time.time_ns() + 3600 * 10**9))
    assert results(keyed.send(ahead.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.ACCEPTED]
    right = FrameEncoder(first_seq=1100, signer=Signer(KEY, 12))
    [refused] = keyed.send(right.encode(messages.Hover(depth_m=0.3), ACK).wire)
    nonce = resync_nonce(refused.reason)
    assert refused.result == AckResult.UNAUTHORIZED and nonce is not None, refused
    [synced] = keyed.send(right.encode(messages.ParamSet(index=-1, value=float(nonce), name=RESYNC_NAME), ACK).wire)
    assert synced.result == AckResult.ACCEPTED and "re-synced" in synced.reason, synced
    keyed.agent._lib.host_init(9, KEY)  # reboot: RAM state gone, the nv area kept
    later = FrameEncoder(first_seq=1200, signer=Signer(KEY, 13, lambda: time.time_ns() + 11 * 10**9))
    assert results(keyed.send(later.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.ACCEPTED]


def test_unsigned_or_wrongly_signed_surface_runs_and_says_so(keyed: KeyedAgent) -> None:
    """SPEC.md 1.2 s. 12, emergencies: anyone may make a keyed agent surface; the ACK says it ran unverified."""
    ground = FrameEncoder(first_seq=600, signer=Signer(KEY, 9))
    assert results(keyed.send(ground.encode(messages.Hover(depth_m=0.2), ACK).wire)) == [AckResult.ACCEPTED]
    plain = FrameEncoder(first_seq=700)
    assert results(keyed.send(plain.encode(messages.Hover(depth_m=0.3), ACK).wire)) == [AckResult.UNAUTHORIZED]
    surface = plain.encode(messages.Surface(), ACK).wire
    acks = keyed.send(surface)
    assert results(acks) == [AckResult.ACCEPTED] and "without a valid signature" in acks[0].reason
    assert keyed.texts() == 1  # HOVER -> SURFACING
    assert results(keyed.send(surface)) == [AckResult.ACCEPTED] and keyed.texts() == 0  # from the ACK memory
    other = FrameEncoder(first_seq=800, signer=Signer(bytes(32), 3))
    assert results(keyed.send(other.encode(messages.Surface(), ACK).wire)) == [AckResult.ACCEPTED]
    assert keyed.agent.counters()["signing_rejects"] == 1  # the unsigned CMD_HOVER only


def test_a_ground_hello_empties_the_ack_memory(keyed: KeyedAgent) -> None:
    """SPEC.md 1.2 s. 5 (G1): after a ground HELLO, a remembered (msg_id, seq) is not answered from memory: with a
    key its old timestamp is then refused as replayed, never given a stale ACK."""
    from protocol import NodeKind, definitions_hash

    ground = FrameEncoder(first_seq=900, signer=Signer(KEY, 10))
    wire = ground.encode(messages.Hover(depth_m=0.2), ACK).wire
    assert results(keyed.send(wire)) == [AckResult.ACCEPTED]
    assert results(keyed.send(wire)) == [AckResult.ACCEPTED]  # remembered
    hello = messages.Hello(protocol_version=1, node_kind=int(NodeKind.GROUND), definitions_hash=definitions_hash(),
                           node_id=7, boot_id=1)
    keyed.send(ground.encode(hello).wire)
    assert results(keyed.send(wire)) == [AckResult.UNAUTHORIZED]  # memory emptied: the timestamp is a replay


def test_a_clock_ahead_moves_the_estimate_a_bounded_step(keyed: KeyedAgent) -> None:
    """Issue 25 L5: one accepted frame moves the estimate at most 10 s (SPEC s. 12, step 5); a clock 59 s ahead can
    no longer ratchet it a minute per frame until a new ground with the right time is refused as too old."""
    clock = Clock()
    honest = FrameEncoder(600, signer=Signer(KEY, 10, clock))
    assert results(keyed.send(honest.encode(messages.ParamGet(index=0), ACK).wire)) == [AckResult.ACCEPTED]
    fast = Clock()
    fast.ns = clock.ns + 59 * 10**9
    ahead = FrameEncoder(700, signer=Signer(KEY, 11, fast))
    assert results(keyed.send(ahead.encode(messages.ParamGet(index=0), ACK).wire)) == [AckResult.ACCEPTED]
    fast.ns += 59 * 10**9  # 118 s ahead of the honest clock: the estimate moved 10 s, so this is too new
    assert results(keyed.send(ahead.encode(messages.ParamGet(index=0), ACK).wire)) == [AckResult.UNAUTHORIZED]
    clock.ns += 10**9
    fresh = FrameEncoder(800, signer=Signer(KEY, 12, clock))  # a new link id with the right time
    assert results(keyed.send(fresh.encode(messages.ParamGet(index=0), ACK).wire)) == [AckResult.ACCEPTED]
