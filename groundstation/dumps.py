"""Dump reassembly (SPEC.md section 10): place chunks by offset, find missing ranges, decode by kind."""

from __future__ import annotations

import struct
from dataclasses import dataclass, field

from protocol import DumpKind
from protocol.messages import DumpChunk

_LAYOUT = {DumpKind.VALUES: "f", DumpKind.POLICY: "B", DumpKind.Q_VALUES: "f", DumpKind.COUNTS: "H"}


@dataclass(frozen=True, slots=True)
class Dump:
    """A complete snapshot."""

    dump_id: int
    kind: DumpKind
    episode: int
    data: bytes

    def values(self) -> list[float] | list[int]:
        """The array, flat, state-major (Q values: [s][a]; counts: [a][s][s'])."""
        code = _LAYOUT.get(self.kind, "B")
        count = len(self.data) // struct.calcsize(code)
        return list(struct.unpack(f"<{count}{code}", self.data[: count * struct.calcsize(code)]))

    def as_dict(self) -> dict[str, object]:
        return {"dump_id": self.dump_id, "episode": self.episode, "kind": self.kind.name.lower(),
                "values": self.values()}


@dataclass
class _Partial:
    kind: int
    episode: int
    total: int
    buffer: bytearray
    have: list[tuple[int, int]] = field(default_factory=list)

    def missing(self) -> list[tuple[int, int]]:
        gaps, cursor = [], 0
        for start, end in sorted(self.have):
            if start > cursor:
                gaps.append((cursor, start))
            cursor = max(cursor, end)
        if cursor < self.total:
            gaps.append((cursor, self.total))
        return gaps


class DumpAssembler:
    """Feed DUMP_CHUNKs of any number of snapshots; each completes once every byte has arrived."""

    def __init__(self, keep: int = 8) -> None:
        self._partials: dict[int, _Partial] = {}
        self._done: list[int] = []
        self._keep = keep

    def feed(self, chunk: DumpChunk) -> Dump | None:
        if chunk.dump_id in self._done:
            return None
        part = self._partials.get(chunk.dump_id)
        if part is None:
            part = _Partial(chunk.kind, chunk.episode, chunk.total_bytes, bytearray(chunk.total_bytes))
            self._partials[chunk.dump_id] = part
            while len(self._partials) > self._keep:
                self._partials.pop(next(iter(self._partials)))
        end = min(part.total, chunk.offset + len(chunk.data))
        if end > chunk.offset:
            part.buffer[chunk.offset:end] = chunk.data[: end - chunk.offset]
            part.have.append((chunk.offset, end))
        if part.missing():
            return None
        del self._partials[chunk.dump_id]
        self._done = [*self._done[-self._keep :], chunk.dump_id]
        try:
            kind = DumpKind(part.kind)
        except ValueError:
            return None
        return Dump(chunk.dump_id, kind, part.episode, bytes(part.buffer))

    def missing(self, dump_id: int) -> list[tuple[int, int]]:
        part = self._partials.get(dump_id)
        return part.missing() if part else []

    def pending(self) -> dict[int, tuple[int, list[tuple[int, int]]]]:
        """dump_id -> (kind, missing ranges) of every incomplete snapshot."""
        return {i: (p.kind, p.missing()) for i, p in self._partials.items()}


KEPT_DUMPS = 16  # completed dumps a DumpTracker keeps (the newest)
RE_REQUEST_TRIES = 3  # a snapshot's missing chunks are asked for at most this often
RE_REQUEST_WAIT_S = 0.5  # ... after 0.5 s, 1 s, 1.5 s from its first chunk


class DumpTracker:
    """A session's dumps: which snapshot answered a request, the newest completed ones, chunks to ask again.

    The agent sends two dumps per episode for as long as a session lasts, so only the newest KEPT_DUMPS
    completed ones are kept: a caller of Session.dump() waits for the newest of its kind, and the
    recorder has written the older ones already.
    """

    def __init__(self, keep: int = KEPT_DUMPS) -> None:
        self.assembler = DumpAssembler()
        self._keep = keep
        self._completed: dict[int, Dump] = {}
        self._first_seen: dict[int, tuple[int, float]] = {}  # dump_id -> (kind, first chunk time)
        self._rerequests: dict[int, int] = {}

    @property
    def held(self) -> int:
        """Completed dumps kept (at most `keep`)."""
        return len(self._completed)

    @property
    def tracked(self) -> int:
        """Snapshots whose first-chunk time is still kept."""
        return len(self._first_seen)

    def feed(self, chunk: DumpChunk, now_s: float) -> Dump | None:
        """Place a chunk; the snapshot when it is complete."""
        self._first_seen.setdefault(chunk.dump_id, (chunk.kind, now_s))
        done = self.assembler.feed(chunk)
        if done is not None:
            self._completed[done.dump_id] = done
            while len(self._completed) > self._keep:
                oldest = next(iter(self._completed))
                del self._completed[oldest]
                self._first_seen.pop(oldest, None)
                self._rerequests.pop(oldest, None)
        return done

    def newest_since(self, kind: int, since_s: float) -> Dump | None:
        """The newest snapshot of `kind` whose first chunk came at or after since_s, once it is complete."""
        ids = [i for i, (k, t) in self._first_seen.items() if k == kind and t >= since_s]
        return self._completed.get(max(ids)) if ids else None

    def due_rerequests(self, now_s: float) -> list[tuple[int, int, int, int]]:
        """(kind, dump_id, start, end) of the missing ranges to ask for again now."""
        due: list[tuple[int, int, int, int]] = []
        for dump_id, (kind, gaps) in self.assembler.pending().items():
            first_seen = self._first_seen.get(dump_id, (kind, now_s))[1]
            tries = self._rerequests.get(dump_id, 0)
            if now_s - first_seen < RE_REQUEST_WAIT_S * (tries + 1) or tries >= RE_REQUEST_TRIES:
                continue
            self._rerequests[dump_id] = tries + 1
            due.extend((kind, dump_id, start, end) for start, end in gaps)
        return due
