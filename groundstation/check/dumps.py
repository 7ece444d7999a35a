"""Dumps: every kind in chunks, ranges re-sent from a held snapshot, STALE for what is gone (SPEC.md 10)."""

from __future__ import annotations

from dataclasses import dataclass

from groundstation.check.agent import overridden, reach, states
from groundstation.check.errors import CheckFailed
from groundstation.check.probe import Exchange, Probe, result_name
from groundstation.check.registry import check, expect
from protocol import AckResult, DumpKind, Mode
from protocol import messages as m
from protocol.parameters import SNAPSHOTS_HELD

SECTION = "10 Dumps"
MAX_CHUNK_DATA = 224  # a sender puts at most 224 data bytes in a chunk (decisions: C4)
BYTES_PER_S = 5000  # slowest link a check waits for: 115200 baud carries about 11 kB/s


def expected_size(kind: DumpKind, s: int) -> int:
    return {DumpKind.VALUES: 4 * s, DumpKind.POLICY: s, DumpKind.Q_VALUES: 8 * s, DumpKind.COUNTS: 4 * s * s}[kind]


@dataclass
class Received:
    ex: Exchange
    chunks: list[m.DumpChunk]

    @property
    def dump_id(self) -> int:
        return self.chunks[0].dump_id if self.chunks else 0

    @property
    def total(self) -> int:
        return self.chunks[0].total_bytes if self.chunks else 0

    def data(self) -> bytes:
        return b"".join(c.data for c in self.chunks)


def request(probe: Probe, kind: int, dump_id: int = 0, offset: int = 0, length: int = 0,
            size_hint: int = 0) -> Received:
    """CMD_DUMP and the chunks that follow it, until they cover the range asked for (or the wait runs out)."""
    ex = probe.command(m.DumpRequest(kind=kind, dump_id=dump_id, offset=offset, length=length))
    if ex.result != AckResult.ACCEPTED:
        return Received(ex, [])

    def chunks() -> list[m.DumpChunk]:
        return [c for c in probe.messages(m.DumpChunk, ex.ack_at) if dump_id in (0, c.dump_id)]

    def covered(_: object) -> bool:
        got = chunks()
        if not got:
            return False
        end = got[0].total_bytes if length == 0 else min(got[0].total_bytes, offset + length)
        return sum(len(c.data) for c in got) >= end - offset

    probe.wait(covered, ex.ack_at, probe.timeouts.reply_s + size_hint / BYTES_PER_S)
    got = chunks()
    if got and len({c.dump_id for c in got}) > 1:
        raise CheckFailed(f"one CMD_DUMP answered with chunks of snapshots {sorted({c.dump_id for c in got})}")
    return Received(ex, got)


def _contiguous(r: Received, start: int, end: int, what: str) -> None:
    position = start
    for c in r.chunks:
        expect(len(c.data) <= MAX_CHUNK_DATA, f"{what}: a chunk of {len(c.data)} data bytes (at most 224)")
        expect(c.offset == position, f"{what}: chunk at offset {c.offset}, wanted {position} (in order, no gap)")
        position += len(c.data)
    expect(position == end, f"{what}: chunks cover [{start}, {position}), wanted [{start}, {end})")


def _accepted(r: Received, what: str) -> None:
    expect(r.ex.ack is not None, f"{what}: no ACK")
    expect(r.ex.result == AckResult.ACCEPTED, f"{what}: {result_name(r.ex.result)}, wanted ACCEPTED")


def _refused(probe: Probe, kind: int, dump_id: int, offset: int, length: int, wanted: AckResult, what: str) -> None:
    ex = probe.command(m.DumpRequest(kind=kind, dump_id=dump_id, offset=offset, length=length))
    expect(ex.result == wanted, f"{what}: {result_name(ex.result)}, wanted {wanted.name}")
    probe.barrier()
    expect(not probe.messages(m.DumpChunk, ex.sent_at), f"{what}: DUMP_CHUNKs followed the NACK")


@check("dump.kinds", SECTION, """dump_id = 0: the agent takes a new snapshot of that kind (new dump_id, never 0),
       ACKs, and sends DUMP_CHUNKs covering [offset, offset + length) (length 0 = to the end) in order, each with
       at most 224 bytes of data. Layouts: VALUES 4 S, POLICY S, Q_VALUES 8 S, COUNTS 4 S² bytes.""")
def kinds(probe: Probe) -> str:
    s = states(probe)
    sizes = []
    for kind in DumpKind:
        size = expected_size(kind, s)
        r = request(probe, int(kind), size_hint=size)
        _accepted(r, f"CMD_DUMP {kind.name}")
        expect(bool(r.chunks), f"{kind.name}: no DUMP_CHUNK after the ACK")
        expect(r.dump_id != 0, f"{kind.name}: dump_id 0")
        expect(all(c.kind == kind for c in r.chunks), f"{kind.name}: chunks of another kind")
        expect(r.total == size, f"{kind.name}: total_bytes {r.total}, wanted {size} for S = {s}")
        _contiguous(r, 0, size, kind.name)
        sizes.append(f"{kind.name} {size} B")
    return f"S = {s}: " + ", ".join(sizes)


@check("dump.partial", SECTION, """dump_id ≠ 0: that snapshot. offset > the snapshot's size → BAD_VALUE.
       offset = size → ACCEPTED, no chunk. [...] a range past the end is cut at the end.""")
def partial(probe: Probe) -> str:
    whole = request(probe, int(DumpKind.Q_VALUES), size_hint=8 * 1024)
    _accepted(whole, "CMD_DUMP Q_VALUES")
    total, data, dump_id = whole.total, whole.data(), whole.dump_id
    expect(total > 60, f"Q_VALUES snapshot of {total} bytes is too small to cut")
    again = request(probe, int(DumpKind.Q_VALUES), dump_id, 10, total // 2)
    _accepted(again, "the re-request of a range")
    _contiguous(again, 10, 10 + total // 2, "re-sent range")
    expect(again.data() == data[10 : 10 + total // 2], "the re-sent range differs from the first sending")
    tail = request(probe, int(DumpKind.Q_VALUES), dump_id, total - 7, 1000)
    _accepted(tail, "a range past the end")
    _contiguous(tail, total - 7, total, "a range past the end")
    at_end = probe.command(m.DumpRequest(kind=int(DumpKind.Q_VALUES), dump_id=dump_id, offset=total, length=0))
    expect(at_end.result == AckResult.ACCEPTED, f"offset = size: {result_name(at_end.result)}, wanted ACCEPTED")
    probe.barrier()
    expect(not probe.messages(m.DumpChunk, at_end.sent_at), "offset = size: chunks were sent")
    _refused(probe, int(DumpKind.Q_VALUES), dump_id, total + 1, 0, AckResult.BAD_VALUE, "offset = size + 1")
    return f"range re-sent byte-identical; cut at the end; offset = size empty; size + 1 refused ({total} B)"


@check("dump.bad_kind", SECTION, "kind not 1-4 → BAD_VALUE. After a NACK nothing follows.")
def bad_kind(probe: Probe) -> str:
    for kind in (0, 5, 255):
        _refused(probe, kind, 0, 0, 0, AckResult.BAD_VALUE, f"kind {kind}")
    return "kinds 0, 5, 255: BAD_VALUE"


@check("dump.stale", SECTION, """if the agent does not hold it, or it is of another kind → STALE. The agent keeps
       the newest 4 snapshots (of any kind); a request for an older id is STALE.""")
def stale(probe: Probe) -> str:
    taken = [request(probe, int(DumpKind.POLICY), size_hint=4096) for _ in range(SNAPSHOTS_HELD + 1)]
    for r in taken:
        _accepted(r, "CMD_DUMP POLICY")
        expect(bool(r.chunks), "CMD_DUMP POLICY: no chunk")
    ids = [r.dump_id for r in taken]
    expect(len(set(ids)) == len(ids), f"snapshots share ids: {ids}")
    _refused(probe, int(DumpKind.POLICY), ids[0], 0, 1, AckResult.STALE,
             f"the snapshot {SNAPSHOTS_HELD + 1} snapshots back")
    for dump_id in ids[1:]:
        r = request(probe, int(DumpKind.POLICY), dump_id, 0, 1)
        _accepted(r, f"one of the newest {SNAPSHOTS_HELD} snapshots")
    _refused(probe, int(DumpKind.VALUES), ids[-1], 0, 1, AckResult.STALE, "a POLICY snapshot asked for as VALUES")
    unknown = (max(ids) + 100_000) & 0xFFFFFFFF or 1
    _refused(probe, int(DumpKind.POLICY), unknown, 0, 1, AckResult.STALE, "a dump_id never issued")
    return f"newest {SNAPSHOTS_HELD} held, the one before STALE; wrong kind and unknown id STALE"


@check("dump.counts_stale", SECTION, """A COUNTS snapshot [...] goes STALE when the model changes (the next
       observed transition, CMD_RESET_MODEL, or a learner parameter change).""", motion=True)
def counts_stale(probe: Probe) -> str:
    reach(probe, Mode.IDLE)
    first = request(probe, int(DumpKind.COUNTS), 0, 0, 1)
    _accepted(first, "CMD_DUMP COUNTS")
    reach(probe, Mode.LEARNING)
    start = probe.end
    found = probe.wait_message(m.Sample, start, probe.timeouts.mode_s,
                               lambda s: s.mode == Mode.LEARNING and s.step >= 2)
    expect(found is not None, "no learning step observed")
    _refused(probe, int(DumpKind.COUNTS), first.dump_id, 0, 1, AckResult.STALE,
             "a COUNTS snapshot after the model learned")
    reach(probe, Mode.IDLE)
    return "STALE after learning steps"


NATURAL_END_WAIT_S = 5.0  # how long an episode may end on its own before the check ends it (CMD_STOP)


@check("dump.each_episode", SECTION, """If the parameter dump_each_episode is 1, the agent sends a VALUES snapshot
       and then a POLICY snapshot (new ids, all chunks, unprompted) after every EPISODE_END, aborted ones included
       (1.2).""", motion=True)
def each_episode(probe: Probe) -> str:
    s = states(probe)
    with overridden(probe, {"dump_each_episode": 1.0}):
        reach(probe, Mode.LEARNING)
        since = probe.end
        end = probe.wait_message(m.EpisodeEnd, since, NATURAL_END_WAIT_S)
        how = "EPISODE_END"
        if end is None:
            how = "EPISODE_END aborted (CMD_STOP)"
            # A learner that holds the depth lasts success_time_s (300 s): end the episode ourselves. SPEC 1.2 s. 10:
            # the dumps follow every EPISODE_END, an aborted one too.
            stop = probe.accepted(m.Stop(), "CMD_STOP (to end the episode)")
            end = probe.wait_message(m.EpisodeEnd, since, probe.timeouts.reply_s)
            del stop
        expect(end is not None, f"no EPISODE_END after the episode's CMD_STOP within {probe.timeouts.reply_s:g} s")
        assert end is not None
        size = 5 * s

        def both(_: object) -> bool:
            got = probe.messages(m.DumpChunk, end[0])
            return sum(len(c.data) for c in got) >= size

        # Not a reply's time: the agent may plan first (the C firmware sends them once its value iteration, run in
        # slices through the next recovery, is done: seconds at --speed 1), so as long as a mode change may take.
        probe.wait(both, end[0], probe.timeouts.mode_s + size / BYTES_PER_S)
        kinds_seen = [c.kind for c in probe.messages(m.DumpChunk, end[0])]
        order = [k for i, k in enumerate(kinds_seen) if i == 0 or kinds_seen[i - 1] != k]
        expect(order[:2] == [int(DumpKind.VALUES), int(DumpKind.POLICY)],
               f"after EPISODE_END came chunks of kinds {order[:4]}, wanted VALUES then POLICY")
    reach(probe, Mode.IDLE)
    return f"VALUES then POLICY after {how}"
