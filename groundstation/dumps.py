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
