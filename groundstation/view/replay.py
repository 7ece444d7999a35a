"""Replay of an MCAP recording into the view: decode its raw frames, pick a range, convert or play in agent time."""

from __future__ import annotations

import dataclasses
import json
import re
import time
from binascii import crc_hqx
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from groundstation.mcap_io import RecordingContents, iter_messages, iter_topic_data
from groundstation.recording.columns import record_dtype
from groundstation.recording.files import RecordingParts as Parts
from groundstation.recording.files import group_recordings
from groundstation.view.errors import ReplayError
from groundstation.view.model import Batch, ViewModel
from protocol import (
    PROTOCOL_VERSION,
    FrameError,
    FrameFlag,
    Message,
    NodeKind,
    PayloadError,
    UnknownMessageError,
    message_class,
)
from protocol import messages as m
from protocol.crc import CRC_INIT
from protocol.enums import INCOMPATIBLE_FLAGS_MASK
from protocol.frame import MIN_INNER, parse_inner

RAW_RX_TOPIC = "/raw/rx"
_TIME = re.compile(r"^(\d+(?:\.\d*)?)(s|m|h|min)$")
_UNIT_S = {"s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}


@dataclass(frozen=True, slots=True)
class Bound:
    """One end of a replay range: an episode number of a chapter, or a time since the recording's start.

    A learner restart (SPEC 1.3 s. 6) or a reboot numbers the episodes from 1 again: the chapter (1, 2, ... in the
    recording, as `dive log info` numbers them) tells the two learners' episode 5 apart.
    """

    episode: int | None = None
    offset_s: float | None = None
    chapter: int = 1


def parse_bound(text: str) -> Bound:
    """`12` or `e12` is episode 12 (of the first chapter); `2:5` is chapter 2's episode 5; `90s`, `5m`, `1.5h` is a
    time since the start of the recording."""
    text = text.strip().lower()
    chapter, _, episode = text.rpartition(":")
    if episode.removeprefix("e").isdigit() and (not chapter or chapter.isdigit() and int(chapter) >= 1):
        return Bound(episode=int(episode.removeprefix("e")), chapter=int(chapter) if chapter else 1)
    match = _TIME.match(text)
    if match is None:
        raise ReplayError(f"bad range bound {text!r}: give an episode (12, or 2:5 for chapter 2's episode 5) or a "
                          "time (90s, 5m, 1h)")
    return Bound(offset_s=float(match.group(1)) * _UNIT_S[match.group(2)])


@dataclass(frozen=True, slots=True)
class Item:
    """One thing to show, in file order: a decoded frame or a ground-station record (/event, /link, /marker)."""

    host_time_ns: int
    agent_time_s: float | None  # the message's own clock, when it has one
    episode: int | None
    feed: Callable[[ViewModel], None]
    setup: bool = False  # state the view needs whatever the window (a parameter: the grid's size), no rows
    before: bool = False  # before the window: fed for the state it leaves (dumps, learning curve), not shown
    generation: int = 0  # the learner generation the frame names (SPEC 1.3), 0 if none
    starts_episode: bool = False
    boot_id: int | None = None  # an agent HELLO's


class _ChapterCount:
    """Chapters in file order: a new one where the learner generation changes, the boot changes, or (a 1.2 agent,
    no generation) an episode starts with a number not above the last one's."""

    def __init__(self) -> None:
        self.chapter = 1
        self._generation = 0
        self._boot_id: int | None = None
        self._last_start = 0

    def follow(self, item: Item) -> int:
        new = False
        if item.boot_id is not None:
            new = self._boot_id is not None and item.boot_id != self._boot_id
            self._boot_id = item.boot_id
            self._generation = 0 if new else self._generation
        if item.generation:
            new = new or (self._generation != 0 and item.generation != self._generation)
            self._generation = item.generation
        elif item.starts_episode and item.episode is not None and 0 < item.episode <= self._last_start:
            new = True
        if new:
            self.chapter, self._last_start = self.chapter + 1, 0
        if item.starts_episode and item.episode is not None:
            self._last_start = item.episode
        return self.chapter


def _decode(inner: bytes) -> tuple[Message, int] | None:
    """A recorded frame's message and flags; None for a damaged frame (skipped as the live decoder would)."""
    try:
        raw = parse_inner(inner)
        return message_class(raw.msg_id).unpack(raw.payload), raw.flags
    except (FrameError, PayloadError, UnknownMessageError, KeyError, ValueError):
        return None


def _frame_item(log_time_ns: int, inner: bytes) -> Item | None:
    decoded = _decode(inner)
    if decoded is None:
        return None
    message, flags = decoded
    t_us = getattr(message, "t_us", None)

    def feed(model: ViewModel) -> None:
        model.feed(message, log_time_ns, flags=flags)

    return Item(log_time_ns, None if t_us is None else t_us / 1e6, getattr(message, "episode", None), feed,
                setup=isinstance(message, m.ParamValue), generation=getattr(message, "generation", 0),
                starts_episode=isinstance(message, m.EpisodeStart),
                boot_id=message.boot_id if isinstance(message, m.Hello) and message.node_kind == NodeKind.AGENT
                else None)


def _json_item(topic: str, log_time_ns: int, data: bytes) -> Item | None:
    try:
        body = json.loads(data)
    except (ValueError, UnicodeDecodeError):
        return None
    if not isinstance(body, dict):
        return None
    if topic == "/link":
        return Item(log_time_ns, None, None, lambda model: model.link_stats(log_time_ns, body))
    if topic == "/marker":
        text = str(body.get("text", ""))
        return Item(log_time_ns, None, None, lambda model: model.event("marker", log_time_ns, text))
    kind, detail = str(body.get("kind", "event")), str(body.get("detail", ""))
    data_dict = body.get("data") if isinstance(body.get("data"), dict) else None
    return Item(log_time_ns, None, None, lambda model: model.event(kind, log_time_ns, detail, data_dict))


_TOPICS = {RAW_RX_TOPIC, "/link", "/event", "/marker"}  # decoded copies (/agent/...) and /dump/... add nothing


def read_items(path: Path, info: RecordingContents | None = None) -> Iterator[Item]:
    """The recording's received frames and ground-station records, in file order (a truncated file: up to the cut)."""
    for record in iter_messages(path, _TOPICS, info):
        if record.topic == RAW_RX_TOPIC:
            item = _frame_item(record.log_time_ns, record.data)
        else:
            item = _json_item(record.topic, record.log_time_ns, record.data)
        if item is not None:
            yield item


def check_order(start: Bound | None, end: Bound | None) -> None:
    """A reversed window is one clear line before anything is read or written."""
    if start is None or end is None:
        return
    if start.episode is not None and end.episode is not None and \
            (start.chapter, start.episode) > (end.chapter, end.episode):
        raise ReplayError(f"--from {_named(start)} is after --to {_named(end)}")
    if start.offset_s is not None and end.offset_s is not None and start.offset_s > end.offset_s:
        raise ReplayError(f"--from {start.offset_s:g} s is after --to {end.offset_s:g} s (agent time)")


@dataclass
class Tally:
    """What select() passed over: items shown (setup left out), and how far the recording reached."""

    shown: int = 0
    span_s: float = 0.0  # agent time from the first frame to the last read
    last_episode: int = 0

    def check_window(self, start: str | None, end: str | None) -> None:
        """A window that holds nothing is an error (a past-the-end --from wrote an almost empty .rrd)."""
        if self.shown == 0 and (start is not None or end is not None):
            window = " ".join(part for part in (f"--from {start}" if start else "", f"--to {end}" if end else "")
                              if part)
            raise ReplayError(f"the window {window} holds no agent frames: the recording spans {self.span_s:.0f} s "
                              f"of agent time and episodes up to {self.last_episode}")


def _named(bound: Bound) -> str:
    return f"episode {bound.episode}" + (f" of chapter {bound.chapter}" if bound.chapter > 1 else "")


def select(items: Iterator[Item], start: Bound | None, end: Bound | None,
           tally: Tally | None = None) -> Iterator[Item]:
    """Only the items inside [start, end]: episodes by the agent's episode number, times in agent time.

    Agent time (the messages' own clock) is the timeline the viewer shows and --speed plays: at --speed max a
    minute of host time holds hours of agent time. A record without a clock of its own (an event, a marker)
    takes the agent time of the frame before it. Backfilled frames come later in the file than their time:
    past a time bound the rest of the file is still read for them.
    """
    first_s: float | None = None
    latest_s = 0.0
    episode = 0
    chapters = _ChapterCount()
    for item in items:
        if item.setup:
            yield item
            continue
        chapter = chapters.follow(item)
        if item.agent_time_s is not None:
            first_s = item.agent_time_s if first_s is None else first_s
            latest_s = item.agent_time_s
        episode = item.episode if item.episode is not None else episode
        offset_s = latest_s - first_s if first_s is not None else 0.0
        if tally is not None:
            tally.span_s, tally.last_episode = max(tally.span_s, offset_s), max(tally.last_episode, episode)
        if start is not None and (
            (start.episode is not None and (chapter, episode) < (start.chapter, start.episode))
            or (start.offset_s is not None and offset_s < start.offset_s)
        ):
            yield dataclasses.replace(item, before=True)  # for the heatmaps and curve the window opens on
            continue
        if end is not None and end.episode is not None and (chapter, episode) > (end.chapter, end.episode):
            break
        if end is not None and end.offset_s is not None and offset_s > end.offset_s:
            continue
        if tally is not None:
            tally.shown += 1
        yield item


def convert(items: Iterator[Item], progress: Callable[[int], None] | None = None) -> tuple[Batch, int]:
    """Feed everything to one model and return all its rows at once (for columnar logging) and the item count."""
    model = ViewModel()
    count, seen, before = 0, 0, False
    for seen, item in enumerate(items, 1):  # noqa: B007
        if item.before:
            item.feed(model)
            before = True
            continue
        if before:  # the window opens on the latest heatmaps and the learning curve so far, not on nothing
            model.keep_state()
            before = False
        item.feed(model)
        count += 1
        if progress is not None and seen % 4096 == 0:
            progress(seen)
    if before:
        model.take()  # all before the window: nothing to show
    return model.take(), count


def convert_recording(path: Path, info: RecordingContents | None = None,
                      progress: Callable[[int], None] | None = None) -> tuple[Batch, int]:
    """The whole file's rows at once (see _convert_into) and the count of items shown."""
    model = ViewModel()
    count = _convert_into(model, path, info, progress)
    return model.take(), count


def _convert_into(model: ViewModel, path: Path, info: RecordingContents | None = None,
                  progress: Callable[[int], None] | None = None, count: int = 0) -> int:
    """convert(read_items(path)) with runs of SAMPLEs decoded and turned into rows as columns.

    A recorded hour holds some 133,000 SAMPLEs: decoding and feeding them one by one is most of a
    conversion. Consecutive intact SAMPLE frames (the exact size this build knows, unsigned, good CRC)
    become one structured array and ViewModel.samples; frames the view ignores (HEARTBEAT, ACK...) are
    counted and do not end a run; every other record takes the per-item path, so episodes, dumps,
    events and damaged frames are shown exactly as convert() shows them (a test compares the two).
    """
    inners: list[bytes] = []
    times: list[int] = []

    def flush() -> None:
        if inners:
            records = np.frombuffer(b"".join([inner[5:-2] for inner in inners]), _SAMPLE_DTYPE)
            model.samples(records, times.copy(), [bool(inner[1] & _REPLAYED) for inner in inners])
            inners.clear()
            times.clear()

    for topic, log_time_ns, data in iter_topic_data(path, _TOPICS, info):
        if topic == RAW_RX_TOPIC:
            if (len(data) == _SAMPLE_SIZE and data[4] == _SAMPLE_ID and data[0] == PROTOCOL_VERSION
                    and not data[1] & _UNCOMMON_FLAGS and not crc_hqx(data, CRC_INIT)):
                inners.append(data)
                times.append(log_time_ns)
                count += 1
                continue
            decoded = _decode(data)
            if decoded is None:
                continue
            count += 1
            if not isinstance(decoded[0], ViewModel.SHOWN):  # HEARTBEAT, ACK...: no rows, no state; the run goes on
                continue
            flush()
            model.feed(decoded[0], log_time_ns, flags=decoded[1])
        else:
            flush()
            item = _json_item(topic, log_time_ns, data)
            if item is not None:
                item.feed(model)
                count += 1
        if progress is not None and count % 4096 == 0:
            progress(count)
    flush()
    return count


_SAMPLE_ID = m.Sample.MSG_ID
_SAMPLE_SIZE = MIN_INNER + m.Sample.DEFINITION.fixed_size
_SAMPLE_DTYPE = record_dtype(m.Sample.DEFINITION)
_REPLAYED = int(FrameFlag.REPLAYED)
_UNCOMMON_FLAGS = INCOMPATIBLE_FLAGS_MASK | int(FrameFlag.SIGNED)  # such a frame takes the per-item path


def play(items: Iterator[Item], sink: Callable[[Callable[[ViewModel], None]], None], speed: float,
         sleep: Callable[[float], None] = time.sleep) -> int:
    """Hand each item to `sink` at its agent time divided by `speed` (backfilled frames: no waiting)."""
    origin_agent_s: float | None = None
    origin_wall = time.monotonic()
    count = 0
    for item in items:
        if item.before:
            continue  # played in time from the window's start (its state would be sent unpaced: not here)
        count += 1
        if item.agent_time_s is not None:
            if origin_agent_s is None:
                origin_agent_s, origin_wall = item.agent_time_s, time.monotonic()
            delay = (item.agent_time_s - origin_agent_s) / speed - (time.monotonic() - origin_wall)
            if delay > 0:
                sleep(delay)
        sink(item.feed)
    return count


def check_nonempty(count: int, path: Path | str, info: RecordingContents) -> None:
    if count == 0:
        cut = " (cut short before its first complete chunk)" if info.truncated else ""
        raise ReplayError(f"{path} holds no agent frames to show{cut}")


# ---------------------------------------------------------------------- several files: the parts of one recording
class MixedRecordingsError(ReplayError):
    """Files of different recordings given to one replay (bad usage: their agent times overlap)."""


def plan(files: list[Path]) -> Parts:
    """The files given as the parts of one recording, in part order, each one's header read first (so a missing
    or non-MCAP file is one line before anything is shown or written).

    Parts of one split recording play as one timeline: the agent's clock runs on across them. Files of different
    recordings are refused: their agent times overlap (each starts near the agent's boot), one timeline cannot
    hold them, and a user replays one session at a time.
    """
    recordings = group_recordings(files)
    if not recordings:
        raise ReplayError("no recording given")
    if len(recordings) > 1:
        names = ", ".join(r.files[0].name for r in recordings[:3]) + (", ..." if len(recordings) > 3 else "")
        raise MixedRecordingsError(
            f"the files hold {len(recordings)} recordings ({names}): dive replay shows one at a time "
            "(a file, or the parts of a split one)")
    return recordings[0]


def header_items(parts: Parts) -> list[Item]:
    """The parameter table the first file's header carries, as the view takes it (a later part holds no PARAM_VALUE
    of its own: without these its value and policy heatmaps would take the default grid)."""
    items: list[Item] = []
    for name, text in (parts.header.get("parameters") or [{}])[-1].items():
        try:
            value = float(text)
        except ValueError:
            continue
        message = m.ParamValue(index=0, count=0, param_type=5, value=value, minimum=value, maximum=value, name=name)
        items.append(Item(0, None, None, _feeder(message), setup=True))
    return items


def _feeder(message: Message) -> Callable[[ViewModel], None]:
    def feed(model: ViewModel) -> None:
        model.feed(message, 0)

    return feed


def read_parts(parts: Parts, infos: list[RecordingContents]) -> Iterator[Item]:
    """The header's items, then every file's items in play order (infos: one per file, filled as they are read)."""
    yield from header_items(parts)
    for path, info in zip(parts.files, infos, strict=True):
        yield from read_items(path, info)


def convert_parts(parts: Parts, infos: list[RecordingContents],
                  progress: Callable[[int], None] | None = None) -> tuple[Batch, int]:
    """convert_recording over every part into one model: one timeline, the view's state carried across parts."""
    model = ViewModel()
    for item in header_items(parts):
        item.feed(model)
    count = 0
    for path, info in zip(parts.files, infos, strict=True):
        count = _convert_into(model, path, info, progress, count)
    return model.take(), count
