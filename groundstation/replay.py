"""Replay of an MCAP recording into the view: decode its raw frames, pick a range, convert or play in agent time."""

from __future__ import annotations

import json
import re
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from groundstation.mcap_io import RecordingContents, iter_messages
from groundstation.view_errors import ReplayError
from groundstation.view_model import Batch, ViewModel
from protocol import FrameError, Message, PayloadError, UnknownMessageError, message_class
from protocol.frame import parse_inner

RAW_RX_TOPIC = "/raw/rx"
_TIME = re.compile(r"^(\d+(?:\.\d*)?)(s|m|h|min)$")
_UNIT_S = {"s": 1.0, "m": 60.0, "min": 60.0, "h": 3600.0}


@dataclass(frozen=True, slots=True)
class Bound:
    """One end of a replay range: an episode number, or a time since the recording's start."""

    episode: int | None = None
    offset_s: float | None = None


def parse_bound(text: str) -> Bound:
    """`12` or `e12` is episode 12; `90s`, `5m`, `1.5h` is a time since the start of the recording."""
    text = text.strip().lower()
    if text.removeprefix("e").isdigit():
        return Bound(episode=int(text.removeprefix("e")))
    match = _TIME.match(text)
    if match is None:
        raise ReplayError(f"bad range bound {text!r}: give an episode (12) or a time (90s, 5m, 1h)")
    return Bound(offset_s=float(match.group(1)) * _UNIT_S[match.group(2)])


@dataclass(frozen=True, slots=True)
class Item:
    """One thing to show, in file order: a decoded frame or a ground-station record (/event, /link, /marker)."""

    host_time_ns: int
    agent_time_s: float | None  # the message's own clock, when it has one
    episode: int | None
    feed: Callable[[ViewModel], None]


def _frame_item(log_time_ns: int, inner: bytes) -> Item | None:
    try:
        raw = parse_inner(inner)
        message: Message = message_class(raw.msg_id).unpack(raw.payload)
    except (FrameError, PayloadError, UnknownMessageError, KeyError, ValueError):
        return None  # a damaged frame in the file: skip it as the live decoder would have
    t_us = getattr(message, "t_us", None)
    flags = raw.flags

    def feed(model: ViewModel) -> None:
        model.feed(message, log_time_ns, flags=flags)

    return Item(log_time_ns, None if t_us is None else t_us / 1e6, getattr(message, "episode", None), feed)


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
    if start.episode is not None and end.episode is not None and start.episode > end.episode:
        raise ReplayError(f"--from episode {start.episode} is after --to episode {end.episode}")
    if start.offset_s is not None and end.offset_s is not None and start.offset_s > end.offset_s:
        raise ReplayError(f"--from {start.offset_s:g} s is after --to {end.offset_s:g} s (agent time)")


def select(items: Iterator[Item], start: Bound | None, end: Bound | None) -> Iterator[Item]:
    """Only the items inside [start, end]: episodes by the agent's episode number, times in agent time.

    Agent time (the messages' own clock) is the timeline the viewer shows and --speed plays: at --speed max a
    minute of host time holds hours of agent time. A record without a clock of its own (an event, a marker)
    takes the agent time of the frame before it. Backfilled frames come later in the file than their time:
    past a time bound the rest of the file is still read for them.
    """
    first_s: float | None = None
    latest_s = 0.0
    episode = 0
    for item in items:
        if item.agent_time_s is not None:
            first_s = item.agent_time_s if first_s is None else first_s
            latest_s = item.agent_time_s
        episode = item.episode if item.episode is not None else episode
        offset_s = latest_s - first_s if first_s is not None else 0.0
        if start is not None and (
            (start.episode is not None and episode < start.episode)
            or (start.offset_s is not None and offset_s < start.offset_s)
        ):
            continue
        if end is not None and end.episode is not None and episode > end.episode:
            break
        if end is not None and end.offset_s is not None and offset_s > end.offset_s:
            continue
        yield item


def convert(items: Iterator[Item], progress: Callable[[int], None] | None = None) -> tuple[Batch, int]:
    """Feed everything to one model and return all its rows at once (for columnar logging) and the item count."""
    model = ViewModel()
    count = 0
    for count, item in enumerate(items, 1):  # noqa: B007 (count is the result)
        item.feed(model)
        if progress is not None and count % 4096 == 0:
            progress(count)
    return model.take(), count


def play(items: Iterator[Item], sink: Callable[[Callable[[ViewModel], None]], None], speed: float,
         sleep: Callable[[float], None] = time.sleep) -> int:
    """Hand each item to `sink` at its agent time divided by `speed` (backfilled frames: no waiting)."""
    origin_agent_s: float | None = None
    origin_wall = time.monotonic()
    count = 0
    for count, item in enumerate(items, 1):  # noqa: B007 (count is the result)
        if item.agent_time_s is not None:
            if origin_agent_s is None:
                origin_agent_s, origin_wall = item.agent_time_s, time.monotonic()
            delay = (item.agent_time_s - origin_agent_s) / speed - (time.monotonic() - origin_wall)
            if delay > 0:
                sleep(delay)
        sink(item.feed)
    return count


def check_nonempty(count: int, path: Path, info: RecordingContents) -> None:
    if count == 0:
        cut = " (cut short before its first complete chunk)" if info.truncated else ""
        raise ReplayError(f"{path} holds no agent frames to show{cut}")
