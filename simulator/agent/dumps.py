"""Dump snapshots of the learner (SPEC.md section 10): byte layouts, a store of recent ones, and chunking."""

from __future__ import annotations

from collections import OrderedDict
from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from learning import Learner
from protocol import Action, DumpKind, messages
from protocol.parameters import SNAPSHOTS_HELD

CHUNK_BYTES = 224  # SPEC s. 10: a sender puts at most 224 bytes of data in a DUMP_CHUNK (a receiver takes 230)


def snapshot_bytes(learner: Learner, kind: DumpKind) -> bytes:
    """The snapshot of one kind, little-endian, state-major."""
    if kind == DumpKind.VALUES:
        return learner.values.astype("<f4").tobytes()
    if kind == DumpKind.Q_VALUES:
        return learner.live_q_values().astype("<f4").tobytes()
    counts = learner.counts  # C[s, s', a]
    if kind == DumpKind.POLICY:
        policy = learner.policy.astype(np.uint8)
        policy[counts.sum(axis=(1, 2)) == 0] = Action.NONE  # untried: never left this state
        return policy.tobytes()
    if kind == DumpKind.COUNTS:
        return np.ascontiguousarray(counts.transpose(2, 0, 1)).astype("<u2").tobytes()
    raise ValueError(f"unknown dump kind {kind}")


BYTES_PER_STATE = {DumpKind.VALUES: 4, DumpKind.POLICY: 1, DumpKind.Q_VALUES: 8}  # COUNTS: 4 S per state


def snapshot_size(states: int, kind: DumpKind) -> int:
    """A snapshot's size before it is taken (SPEC s. 10 layouts): a request refused for its offset takes none."""
    return BYTES_PER_STATE.get(kind, 4 * states) * states


@dataclass(frozen=True)
class Snapshot:
    dump_id: int
    kind: DumpKind
    episode: int
    data: bytes


def rendered_live(learner: Learner, kind: DumpKind) -> bool:
    """Snapshots an agent renders from its live learner instead of copying (SPEC.md sections 10 and 13): COUNTS,
    and Q_VALUES of a shared-model learner (it keeps no Q table: Q comes from its values and histograms)."""
    return kind == DumpKind.COUNTS or (kind == DumpKind.Q_VALUES and learner.config.shared_model)


class DumpStore:
    """Takes snapshots with fresh ids (never 0) and keeps the last SNAPSHOTS_HELD (4) of them (SPEC s. 10).

    A real agent renders a COUNTS snapshot (and a shared model's Q_VALUES) from its live learner instead of
    copying it, so one goes STALE when the model changes; this store copies it (the same bytes) and forgets it
    at the same moment. (This agent plans at once at the end of an episode, right after the model changed, so
    a live snapshot taken after that stays valid until the next change.)
    """

    def __init__(self) -> None:
        self._held: OrderedDict[int, Snapshot] = OrderedDict()
        self._next_id = 1
        self._live_ids: set[int] = set()  # checked on every learner step, so model_changed() costs nothing usually

    def take(self, learner: Learner, kind: DumpKind) -> Snapshot:
        snap = Snapshot(self._next_id, kind, learner.episode, snapshot_bytes(learner, kind))
        self._next_id = self._next_id % 0xFFFFFFFF + 1
        self._held[snap.dump_id] = snap
        if rendered_live(learner, kind):
            self._live_ids.add(snap.dump_id)
        while len(self._held) > SNAPSHOTS_HELD:
            dropped, _ = self._held.popitem(last=False)
            self._live_ids.discard(dropped)
        return snap

    def get(self, dump_id: int) -> Snapshot | None:
        return self._held.get(dump_id)

    def model_changed(self) -> None:
        """Forget the snapshots rendered live: the model they stand for has changed."""
        if self._live_ids:
            for dump_id in self._live_ids:
                self._held.pop(dump_id, None)
            self._live_ids.clear()


def chunks(snap: Snapshot, offset: int, length: int) -> Iterator[messages.DumpChunk]:
    """DUMP_CHUNKs covering [offset, offset + length) of the snapshot (length 0 = to the end)."""
    total = len(snap.data)
    end = total if length == 0 else min(total, offset + length)
    for start in range(offset, end, CHUNK_BYTES):
        yield messages.DumpChunk(
            dump_id=snap.dump_id, kind=int(snap.kind), episode=snap.episode, total_bytes=total, offset=start,
            data=snap.data[start : min(end, start + CHUNK_BYTES)],
        )
