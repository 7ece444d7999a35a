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
        """As JSON has it (`dive dump`, the recording's /dump topics): a float32 as the shortest number that is the
        same float32 (-3.2, not -3.200000047683716), as the agent stored it."""
        values = self.values()
        if _LAYOUT.get(self.kind) == "f":
            import numpy as np  # here: the session's other paths do not need it

            values = [float(str(v)) for v in np.asarray(values, dtype=np.float32)]
        return {"dump_id": self.dump_id, "episode": self.episode, "kind": self.kind.name.lower(), "values": values}


@dataclass
class _Partial:
    kind: int
    episode: int
    total: int
    buffer: bytearray
    have: list[tuple[int, int]] = field(default_factory=list)

    def add(self, start: int, end: int) -> None:
        """Note [start, end) as received, merging ranges (a chunk sent again must not grow the list)."""
        merged: list[tuple[int, int]] = []
        for a, b in sorted([*self.have, (start, end)]):
            if merged and a <= merged[-1][1]:
                merged[-1] = (merged[-1][0], max(b, merged[-1][1]))
            else:
                merged.append((a, b))
        self.have = merged

    def missing(self) -> list[tuple[int, int]]:
        gaps, cursor = [], 0
        for start, end in sorted(self.have):
            if start > cursor:
                gaps.append((cursor, start))
            cursor = max(cursor, end)
        if cursor < self.total:
            gaps.append((cursor, self.total))
        return gaps


# Untrusted sizes (issue 13 item 1): a chunk's total_bytes is checked against what the agent can hold before a
# byte is allocated. S = z_cells * zdot_cells * act_bins + 1 comes from the agent's parameters (PARAM_VALUE) when
# they have been seen; until then S is taken as at most UNKNOWN_GRID_STATES, the most any agent can hold.
HELD_SNAPSHOTS = 4  # the agent keeps the newest 4 snapshots (SPEC.md 1.1); an older one can never be completed
# SPEC.md s. 10/13: the largest S the RAM budget admits: 316 for the paper's model, 2 071 for the shared model
# (z_cells 46, zdot_cells 45), whose COUNTS is then 17 156 164 bytes; a test derives it from the RAM formula.
UNKNOWN_GRID_STATES = 2071
_GRID_PARAMETERS = ("z_cells", "zdot_cells", "act_bins")


def snapshot_bytes(kind: int, states: int) -> int:
    """The size of a snapshot of `kind` for S = `states` (SPEC.md section 10); 0 for an unknown kind."""
    return {DumpKind.VALUES: 4 * states, DumpKind.POLICY: states, DumpKind.Q_VALUES: 8 * states,
            DumpKind.COUNTS: 4 * states * states}.get(kind, 0)  # type: ignore[call-overload]


class DumpAssembler:
    """Feed DUMP_CHUNKs of any number of snapshots; each completes once every byte has arrived.

    At most `keep` incomplete snapshots are held (the oldest is dropped), each no larger than the agent's grid
    allows; a chunk announcing more is counted in `refused` and dropped.
    """

    def __init__(self, keep: int = HELD_SNAPSHOTS) -> None:
        self._partials: dict[int, _Partial] = {}
        self._done: list[int] = []
        self._keep = keep
        self._grid: dict[str, int] = {}
        self.refused = 0

    def saw_parameter(self, name: str, value: float) -> None:
        """Learn the grid size from the agent's PARAM_VALUEs (any other name is ignored)."""
        if name in _GRID_PARAMETERS and 1 <= value <= 255:
            self._grid[name] = int(value)

    @property
    def states(self) -> int:
        """S as the agent's parameters give it, else the bound assumed for an agent not yet asked."""
        if len(self._grid) == len(_GRID_PARAMETERS):
            return self._grid["z_cells"] * self._grid["zdot_cells"] * self._grid["act_bins"] + 1
        return UNKNOWN_GRID_STATES

    def limit(self, kind: int) -> int:
        return snapshot_bytes(kind, self.states)

    def feed(self, chunk: DumpChunk) -> Dump | None:
        if chunk.dump_id in self._done:
            return None
        part = self._partials.get(chunk.dump_id)
        if part is None:
            if not 0 < chunk.total_bytes <= self.limit(chunk.kind):
                self.refused += 1
                return None
            part = _Partial(chunk.kind, chunk.episode, chunk.total_bytes, bytearray(chunk.total_bytes))
            self._partials[chunk.dump_id] = part
            while len(self._partials) > self._keep:
                self._partials.pop(next(iter(self._partials)))
        end = min(part.total, chunk.offset + len(chunk.data))
        if end > chunk.offset:
            part.buffer[chunk.offset:end] = chunk.data[: end - chunk.offset]
            part.add(chunk.offset, end)
        if part.missing():
            return None
        del self._partials[chunk.dump_id]
        self._done = [*self._done[-self._keep :], chunk.dump_id]
        try:
            kind = DumpKind(part.kind)
        except ValueError:
            return None
        return Dump(chunk.dump_id, kind, part.episode, bytes(part.buffer))

    def holds(self, dump_id: int) -> bool:
        """True while `dump_id` is being assembled."""
        return dump_id in self._partials

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
        done = self.assembler.feed(chunk)
        if done is None and not self.assembler.holds(chunk.dump_id):
            return None  # refused (too large) or long finished: no bookkeeping for it, however many ids come
        self._first_seen.setdefault(chunk.dump_id, (chunk.kind, now_s))
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
