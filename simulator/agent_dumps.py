"""Dump snapshots of the learner (SPEC.md section 10): byte layouts, a store of recent ones, and chunking."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from learning import Learner
from protocol import Action, DumpKind, messages

CHUNK_BYTES = 224  # SPEC s. 10: at most 224 bytes of data per DUMP_CHUNK
SNAPSHOTS_HELD = 8  # older snapshots are forgotten: a re-request for one gets NACK STALE


def snapshot_bytes(learner: Learner, kind: DumpKind) -> bytes:
    """The snapshot of one kind, little-endian, state-major."""
    if kind == DumpKind.VALUES:
        return learner.values.astype("<f4").tobytes()
    if kind == DumpKind.Q_VALUES:
        return learner.q_values.astype("<f4").tobytes()
    counts = learner.counts  # C[s, s', a]
    if kind == DumpKind.POLICY:
        policy = learner.policy.astype(np.uint8)
        policy[counts.sum(axis=(1, 2)) == 0] = Action.NONE  # untried: never left this state
        return policy.tobytes()
    if kind == DumpKind.COUNTS:
        return np.ascontiguousarray(counts.transpose(2, 0, 1)).astype("<u2").tobytes()
    raise ValueError(f"unknown dump kind {kind}")


@dataclass(frozen=True)
class Snapshot:
    dump_id: int
    kind: DumpKind
    episode: int
    data: bytes


class DumpStore:
    """Takes snapshots with fresh ids (never 0) and keeps the last SNAPSHOTS_HELD of them."""

    def __init__(self) -> None:
        self._held: OrderedDict[int, Snapshot] = OrderedDict()
        self._next_id = 1

    def take(self, learner: Learner, kind: DumpKind) -> Snapshot:
        snap = Snapshot(self._next_id, kind, learner.episode, snapshot_bytes(learner, kind))
        self._next_id = self._next_id % 0xFFFFFFFF + 1
        self._held[snap.dump_id] = snap
        while len(self._held) > SNAPSHOTS_HELD:
            self._held.popitem(last=False)
        return snap

    def get(self, dump_id: int) -> Snapshot | None:
        return self._held.get(dump_id)


def chunks(snap: Snapshot, offset: int, length: int) -> Iterator[messages.DumpChunk]:
    """DUMP_CHUNKs covering [offset, offset + length) of the snapshot (length 0 = to the end)."""
    total = len(snap.data)
    end = total if length == 0 else min(total, offset + length)
    for start in range(offset, end, CHUNK_BYTES):
        yield messages.DumpChunk(
            dump_id=snap.dump_id, kind=int(snap.kind), episode=snap.episode, total_bytes=total, offset=start,
            data=snap.data[start : min(end, start + CHUNK_BYTES)],
        )
