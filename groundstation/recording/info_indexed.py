"""`dive log info` of a finished recording through its chunk and message indexes: counts from the indexes, SAMPLEs
decoded as columns from their raw frames, only the few other messages a summary needs decoded one by one.

The result is the one the stream reader gives (info.summarize_stream; a test compares the two on every kind of
recording): the recorder writes each received frame as its JSON copy (/agent/NAME) followed at once by the raw
frame (/raw/rx) with the same log time, so a SAMPLE's JSON is read from its raw twin, 48 bytes at a fixed place,
with numpy over all of a chunk's SAMPLEs at once. A JSON SAMPLE without such a twin (another tool wrote it) is
decoded as JSON, as the stream reader does. Memory stays constant: one chunk at a time, the held sample indices
as ranges.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from groundstation.mcap_io import RecordedMessage
from groundstation.mcap_io.indexed import (
    MESSAGE_DATA_AT,
    MESSAGE_LOG_TIME_AT,
    IndexedChunk,
    IndexedFile,
    iter_indexed_chunks,
)
from groundstation.recording.chapters import CHAPTER_TOPICS, Chapters, follow_recorded
from groundstation.recording.columns import record_dtype
from groundstation.recording.recorded import Boots, json_fields
from groundstation.session.exactness import MAX_SAMPLE_RATE_HZ, SAMPLE_SLACK
from protocol import PROTOCOL_VERSION, FrameFlag
from protocol import messages as m
from protocol.enums import INCOMPATIBLE_FLAGS_MASK
from protocol.frame import MIN_INNER

SAMPLE_TOPIC, RAW_RX_TOPIC = "/agent/SAMPLE", "/raw/rx"
# The few topics decoded one message at a time (about 1 in 30 messages of a run); the rest are only counted.
HEARTBEAT_TOPIC = "/agent/HEARTBEAT"
CONTROL_TOPICS = (HEARTBEAT_TOPIC, "/agent/EPISODE_END", "/event", "/link", *CHAPTER_TOPICS)
_SAMPLE = record_dtype(m.Sample.DEFINITION)
_SAMPLE_INNER = MIN_INNER + _SAMPLE.itemsize
_FIELD_AT = {name: 5 + int(spec[1]) for name, spec in (_SAMPLE.fields or {}).items()}  # in the inner frame
_RAW_RECORD = MESSAGE_DATA_AT - 1 - 8 + _SAMPLE_INNER  # the twin's record length field: channel .. data
_UNCOMMON = INCOMPATIBLE_FLAGS_MASK | int(FrameFlag.SIGNED)
_REPLAYED = int(FrameFlag.REPLAYED)


class HeldIndices:
    """Sample indices held, as sorted disjoint [start, end) ranges in numpy: a chunk's indices are added at once."""

    def __init__(self) -> None:
        self.starts = np.zeros(0, dtype=np.int64)
        self.ends = np.zeros(0, dtype=np.int64)

    def add(self, indices: NDArray[np.int64], backfilled: NDArray[np.bool_]) -> tuple[int, int]:
        """Add indices given in file order; (how many were new, how many of those came first backfilled)."""
        unique, first = np.unique(indices, return_index=True)
        at = np.searchsorted(self.starts, unique, side="right") - 1
        inside = (at >= 0) & (unique < self.ends[np.maximum(at, 0)]) if len(self.starts) else \
            np.zeros(len(unique), dtype=bool)
        new = unique[~inside]
        if len(new):
            breaks = np.flatnonzero(np.diff(new) != 1) + 1
            starts = np.concatenate([self.starts, new[np.r_[0, breaks]]])
            ends = np.concatenate([self.ends, new[np.r_[breaks - 1, len(new) - 1]] + 1])
            order = np.argsort(starts, kind="stable")
            starts, ends = starts[order], ends[order]
            reach = np.maximum.accumulate(ends)
            opens = np.r_[True, starts[1:] > reach[:-1]]  # a range that neither overlaps nor touches the one before
            self.starts = starts[opens]
            self.ends = np.maximum.reduceat(ends, np.flatnonzero(opens))
        return len(new), int(np.count_nonzero(backfilled[first][~inside]))

    @property
    def first(self) -> int | None:
        return int(self.starts[0]) if len(self.starts) else None

    @property
    def end(self) -> int | None:
        return int(self.ends[-1]) if len(self.ends) else None

    def ranges(self) -> list[tuple[int, int]]:
        return [(int(a), int(b)) for a, b in zip(self.starts, self.ends, strict=True)]

    def missing(self) -> int:
        return int(self.ends[-1] - self.starts[0] - np.sum(self.ends - self.starts)) if len(self.starts) else 0


@dataclass
class BootCounts:
    boot: int
    boot_id: int | None = None
    held: HeldIndices = field(default_factory=HeldIndices)
    samples: int = 0
    backfilled: int = 0
    impossible: int = 0


@dataclass
class IndexedTotals:
    """What the chunks held, for info.summarize to put in a RecordingSummary."""

    messages: int = 0
    topics: dict[str, int] = field(default_factory=dict)
    first_ns: int | None = None
    last_ns: int | None = None
    first_us: int | None = None
    last_us: int | None = None
    sessions: int = 0
    link_losses: int = 0
    frames_lost: int = 0
    rejects: int = 0
    malformed: int = 0
    episodes: list[dict[str, Any]] = field(default_factory=list)
    chapters: Chapters = field(default_factory=Chapters)
    boots: list[BootCounts] = field(default_factory=list)
    damaged_chunks: int = 0


class _State:
    """The walk's state between messages: the boot, and the latest HEARTBEAT of this boot (next sample, at us)."""

    def __init__(self, file: IndexedFile, totals: IndexedTotals) -> None:
        self.totals = totals
        self.boots = Boots()
        self.boots.header(file.metadata)
        self.boot = BootCounts(self.boots.current, self.boots.boot_id)
        totals.boots.append(self.boot)
        self.heartbeat: tuple[int, int] | None = None
        self.new_session = True

    def control(self, topic: str, msg: RecordedMessage) -> None:
        """One decoded message of CONTROL_TOPICS, as info.summarize_stream takes it."""
        t = self.totals
        body: dict[str, Any] | None = {}
        if topic == "/agent/EPISODE_END":
            body = json_fields(msg, integers=("episode", "reason", "steps"), numbers=("duration_s", "episode_return"))
            if body is not None:
                t.episodes.append(follow_recorded(t.chapters, self.boots.current, topic, msg.data) or body)
        elif topic in CHAPTER_TOPICS[1:]:  # TEXT, ACK, EPISODE_START: where a chapter begins
            body = follow_recorded(t.chapters, self.boots.current, topic, msg.data)
        elif topic == "/agent/HELLO":
            if self.new_session:
                t.sessions += 1
                self.new_session = False
            if self.boots.hello(msg):
                self.boot = BootCounts(self.boots.current, self.boots.boot_id)
                t.boots.append(self.boot)
                self.heartbeat = None
            self.boot.boot_id = self.boots.boot_id  # the first HELLO of a file without a header names boot 1
            follow_recorded(t.chapters, self.boots.current, topic, msg.data)
        elif topic == "/event":
            body = json_fields(msg)
            if body is not None and body.get("kind") == "link_lost":
                t.link_losses += 1
                self.new_session = True
        elif topic == "/link":
            body = json_fields(msg)
            link = body.get("link") if body is not None else None
            if isinstance(link, dict):
                t.frames_lost, t.rejects = _count(link.get("rx_lost")), _count(link.get("rx_rejects"))
        if body is None:
            t.malformed += 1


def summarize_indexed(file: IndexedFile, progress: Callable[[int], None] | None = None) -> IndexedTotals:
    """Walk every chunk of an indexed file (progress: compressed bytes done so far)."""
    totals = IndexedTotals()
    state = _State(file, totals)
    by_topic = {info.topic: cid for cid, info in file.channels.items()}
    sample_id, raw_id = by_topic.get(SAMPLE_TOPIC), by_topic.get(RAW_RX_TOPIC, -1)
    control_ids = {by_topic[topic]: topic for topic in CONTROL_TOPICS if topic in by_topic}
    beat_id = by_topic.get(HEARTBEAT_TOPIC, -1)
    control_ids.pop(beat_id, None)  # a HEARTBEAT a second of agent time: taken in columns (_beats), not one by one
    damaged = [0]
    done = 0
    for chunk in iter_indexed_chunks(file, damaged):
        _count_messages(chunk, file, totals)
        controls = sorted((int(offset), cid) for cid in control_ids if cid in chunk.index
                          for _, offset in chunk.index[cid])
        beats = _beats(chunk, np.sort(chunk.index[beat_id][:, 1]) if beat_id in chunk.index else _NO_OFFSETS, totals)
        samples = chunk_samples(chunk, sample_id, raw_id, totals) if sample_id in chunk.index else None
        _walk(chunk, state, controls, control_ids, beats, samples)
        done += chunk.compressed_size
        if progress is not None:
            progress(done)
    totals.damaged_chunks = damaged[0]
    return totals


def _count_messages(chunk: IndexedChunk, file: IndexedFile, totals: IndexedTotals) -> None:
    for cid, rows in chunk.index.items():
        if not len(rows):
            continue
        topic = file.channels[cid].topic if cid in file.channels else f"channel {cid}"
        totals.topics[topic] = totals.topics.get(topic, 0) + len(rows)
        totals.messages += len(rows)
        lo, hi = int(rows[:, 0].min()), int(rows[:, 0].max())
        totals.first_ns = lo if totals.first_ns is None else min(totals.first_ns, lo)
        totals.last_ns = hi if totals.last_ns is None else max(totals.last_ns, hi)


def _gather(buf: NDArray[np.uint8], at: NDArray[np.int64], dtype: str) -> NDArray[Any]:
    """The little-endian number of type `dtype` at each byte offset `at` of `buf`."""
    size = np.dtype(dtype).itemsize
    return buf[at[:, None] + np.arange(size)].copy().view(dtype).ravel()


_Samples = tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64], NDArray[np.bool_]]


def chunk_samples(chunk: IndexedChunk, sample_id: int | None, raw_id: int, totals: IndexedTotals) -> _Samples:
    """The chunk's SAMPLEs as (offset, sample index, t_us, backfilled), in file order; malformed ones counted."""
    rows = chunk.index[sample_id]  # type: ignore[index]
    offsets = rows[:, 1].astype(np.int64)
    buf = np.frombuffer(chunk.data, dtype=np.uint8)
    lengths = _gather(buf, offsets + 1, "<u8")
    lengths = np.where(lengths < len(buf), lengths, len(buf)).astype(np.int64)  # a hostile length stays in the chunk
    twin = offsets + 9 + lengths
    fits = twin + MESSAGE_DATA_AT + _SAMPLE_INNER <= len(buf)
    ok = np.zeros(len(offsets), dtype=bool)
    at = twin[fits]
    frame = at + MESSAGE_DATA_AT
    ok[fits] = ((buf[at] == 0x05) & (_gather(buf, at + 1, "<u8") == _RAW_RECORD)
                & (_gather(buf, at + 9, "<u2") == raw_id)
                & (_gather(buf, at + MESSAGE_LOG_TIME_AT, "<u8") == rows[fits, 0])
                & (buf[frame] == PROTOCOL_VERSION) & (buf[frame + 4] == m.Sample.MSG_ID)
                & ((buf[frame + 1] & _UNCOMMON) == 0))
    # The chunk's CRC covers the twin; the recorder wrote the JSON from this very frame, so it is not checked again.
    frame = twin[ok] + MESSAGE_DATA_AT
    index = _gather(buf, frame + _FIELD_AT["sample"], "<u4").astype(np.int64)
    t_us = _gather(buf, frame + _FIELD_AT["t_us"], "<u8").astype(np.int64)
    backfilled = (buf[frame + 1] & _REPLAYED) != 0
    kept = offsets[ok]
    if not ok.all():  # JSON without a raw twin: decoded as the stream reader does
        extra: list[tuple[int, int, int, bool]] = []
        for offset in offsets[~ok]:
            body = json_fields(_message(chunk, int(offset), SAMPLE_TOPIC), integers=("sample", "t_us"))
            if body is None or not all(-2**62 < body[k] < 2**62 for k in ("sample", "t_us")):
                totals.malformed += 1  # (an index past int64 is no index an agent can reach)
            else:
                extra.append((int(offset), body["sample"], body["t_us"], bool(body.get("_backfilled"))))
        if extra:
            more = np.array(extra, dtype=np.int64).reshape(-1, 4)
            order = np.argsort(np.concatenate([kept, more[:, 0]]), kind="stable")
            kept = np.concatenate([kept, more[:, 0]])[order]
            index = np.concatenate([index, more[:, 1]])[order]
            t_us = np.concatenate([t_us, more[:, 2]])[order]
            backfilled = np.concatenate([backfilled, more[:, 3].astype(bool)])[order]
    return kept, index, t_us, backfilled


def _message(chunk: IndexedChunk, offset: int, topic: str) -> RecordedMessage:
    length = int.from_bytes(chunk.data[offset + 1: offset + 9], "little")
    log_time = int.from_bytes(chunk.data[offset + MESSAGE_LOG_TIME_AT: offset + MESSAGE_LOG_TIME_AT + 8], "little")
    return RecordedMessage(topic, log_time, log_time, chunk.data[offset + MESSAGE_DATA_AT: offset + 9 + length],
                           "json", "")


def _bodies(chunk: IndexedChunk, offsets: NDArray[np.int64]) -> list[Any] | None:
    """The JSON of the messages at `offsets`, decoded in one call (a recording holds a HEARTBEAT a second of agent
    time: decoding them one by one was most of a summary's time); None when they are not that many JSON values
    (a malformed one: then each is decoded on its own, and counted as malformed as it is)."""
    data = chunk.data
    parts = [data[at + MESSAGE_DATA_AT: at + 9 + int.from_bytes(data[at + 1: at + 9], "little")]
             for at in offsets.tolist()]
    try:
        decoded = json.loads(b"[" + b",".join(parts) + b"]")
    except (ValueError, UnicodeDecodeError):
        return None
    return decoded if isinstance(decoded, list) and len(decoded) == len(parts) else None


_Beats = tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]]  # file offset, log_next_sample, at us
_NO_OFFSETS = np.zeros((0,), dtype=np.int64)


def _beats(chunk: IndexedChunk, offsets: NDArray[np.int64], totals: IndexedTotals) -> _Beats:
    """The chunk's well-formed HEARTBEATs in file order, as columns; the malformed ones counted, then left out."""
    decoded = _bodies(chunk, offsets) if len(offsets) > 1 else None
    if decoded is None:
        decoded = [json_fields(_message(chunk, at, HEARTBEAT_TOPIC)) for at in offsets.tolist()]
    try:  # every one well formed (the rule): columns at C speed
        next_samples = [body["log_next_sample"] for body in decoded]
        uptimes_ms = [body["uptime_ms"] for body in decoded]
        if set(map(type, next_samples)) | set(map(type, uptimes_ms)) <= {int}:  # not bool, float or None
            nexts, uptimes = np.array(next_samples, dtype=np.int64), np.array(uptimes_ms, dtype=np.int64)
            if not len(offsets) or max(np.abs(nexts).max(), np.abs(uptimes).max()) < 2**53:  # no overflow below
                return offsets, nexts, uptimes * 1000
    except (TypeError, KeyError, IndexError, OverflowError):
        pass
    kept_at, kept_next, kept_us = [], [], []
    for at, body in zip(offsets.tolist(), decoded, strict=True):
        try:
            next_sample, uptime_ms = body["log_next_sample"], body["uptime_ms"]
        except (TypeError, KeyError, IndexError):  # not an object, or without the fields (json_fields' checks)
            next_sample = uptime_ms = None
        if type(next_sample) is int and type(uptime_ms) is int and max(abs(next_sample), abs(uptime_ms)) < 2**53:
            kept_at.append(at)
            kept_next.append(next_sample)
            kept_us.append(uptime_ms * 1000)
        else:
            totals.malformed += 1
    return (np.array(kept_at, dtype=np.int64), np.array(kept_next, dtype=np.int64),
            np.array(kept_us, dtype=np.int64))


def _walk(chunk: IndexedChunk, state: _State, controls: list[tuple[int, int]], control_ids: dict[int, str],
          beats: _Beats, samples: _Samples | None) -> None:
    """The control messages one by one in file order (HELLOs start boots); then the SAMPLEs at once, each taken in
    its boot and with the latest HEARTBEAT before it of that boot (a new boot forgets the last one)."""
    start_beat = state.heartbeat or (-1, 0)
    boots: list[BootCounts] = [state.boot]
    boot_of = [0]
    starts: list[int] = []  # file offsets of the controls that began a new boot
    for offset, cid in controls:
        state.control(control_ids[cid], _message(chunk, offset, control_ids[cid]))
        if state.boot is not boots[-1]:
            boots.append(state.boot)
            starts.append(offset)
        boot_of.append(len(boots) - 1)
    beat_at, beat_next, beat_us = beats
    last_start = starts[-1] if starts else -1
    if len(beat_at) and beat_at[-1] > last_start:
        state.heartbeat = (int(beat_next[-1]), int(beat_us[-1]))
    if samples is None:
        return
    offsets, index, t_us, backfilled = samples
    boot = np.array(boot_of, dtype=np.int64)[np.searchsorted(np.array([o for o, _ in controls], dtype=np.int64),
                                                             offsets)]
    started = np.array([-1, *starts], dtype=np.int64)[np.searchsorted(np.array(starts, dtype=np.int64), offsets)]
    latest = np.searchsorted(beat_at, offsets) - 1
    if len(beat_at):
        clipped = np.maximum(latest, 0)
        has = (latest >= 0) & (beat_at[clipped] > started)
        before_next, before_us = beat_next[clipped], beat_us[clipped]
    else:
        has = np.zeros(len(offsets), dtype=bool)
        before_next = before_us = np.zeros(len(offsets), dtype=np.int64)
    carried = started < 0  # no new boot before the sample: the heartbeat from before the chunk still holds
    beat_next_sample = np.where(has, before_next, np.where(carried, start_beat[0], -1))
    beat_at_us = np.where(has, before_us, np.where(carried, start_beat[1], 0))
    elapsed_s = np.maximum(0.0, (t_us - beat_at_us) / 1e6)
    possible = (beat_next_sample < 0) | (index <= beat_next_sample + SAMPLE_SLACK + MAX_SAMPLE_RATE_HZ * elapsed_s)
    t = state.totals
    for number, counts in enumerate(boots):
        mine = boot == number
        counts.impossible += int(np.count_nonzero(mine & ~possible))
        taken = mine & possible
        if not taken.any():
            continue
        lo, hi = int(t_us[taken].min()), int(t_us[taken].max())
        t.first_us = lo if t.first_us is None else min(t.first_us, lo)
        t.last_us = hi if t.last_us is None else max(t.last_us, hi)
        new, new_backfilled = counts.held.add(index[taken], backfilled[taken])
        counts.samples += new
        counts.backfilled += new_backfilled


def _count(value: object) -> int:
    return value if isinstance(value, int) and not isinstance(value, bool) else 0
