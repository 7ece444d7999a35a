"""A recording read for replay: its received frames and ground records as items to feed the view, in file order."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

from groundstation.mcap_io import RecordingContents, iter_topic_data
from groundstation.recording.files import RecordingParts as Parts
from groundstation.recording.recorded import json_object
from groundstation.view.model import ViewModel
from protocol import FrameError, Message, PayloadError, UnknownMessageError, message_class
from protocol import messages as m
from protocol.frame import parse_inner

RAW_RX_TOPIC = "/raw/rx"
TOPICS = {RAW_RX_TOPIC, "/link", "/event", "/marker"}  # decoded copies (/agent/...) and /dump/... add nothing


@dataclass(slots=True)
class Item:
    """One thing to show, in file order: a decoded frame or a ground-station record (/event, /link, /marker).

    Not frozen: a replay window marks the items before it (`before`) in place, 100,000 of them in an hour."""

    host_time_ns: int
    agent_time_s: float | None  # the message's own clock, when it has one
    episode: int | None
    feed: Callable[[ViewModel], None]
    setup: bool = False  # state the view needs whatever the window (a parameter: the grid's size), no rows
    before: bool = False  # before the window: fed for the state it leaves (dumps, learning curve), not shown
    message: Message | None = None  # the agent's frame, decoded (what says where a chapter begins)
    flags: int = 0  # the frame's flags (REPLAYED: backfilled)


def decode(inner: bytes) -> tuple[Message, int] | None:
    """A recorded frame's message and flags; None for a damaged frame (skipped as the live decoder would)."""
    try:
        raw = parse_inner(inner)
        return message_class(raw.msg_id).unpack(raw.payload), raw.flags
    except (FrameError, PayloadError, UnknownMessageError, KeyError, ValueError):
        return None


def _frame_item(log_time_ns: int, inner: bytes) -> Item | None:
    decoded = decode(inner)
    if decoded is None:
        return None
    message, flags = decoded
    t_us = getattr(message, "t_us", None)

    def feed(model: ViewModel) -> None:
        model.feed(message, log_time_ns, flags=flags)

    return Item(log_time_ns, None if t_us is None else t_us / 1e6, getattr(message, "episode", None), feed,
                setup=isinstance(message, m.ParamValue), message=message, flags=flags)


def record_item(topic: str, log_time_ns: int, data: bytes) -> Item | None:
    """A ground-station record (/link, /marker, /event) as an item; None for a body that is not a JSON object."""
    body = json_object(data)
    if body is None:
        return None
    if topic == "/link":
        return Item(log_time_ns, None, None, lambda model: model.link_stats(log_time_ns, body))
    if topic == "/marker":
        text = str(body.get("text", ""))
        return Item(log_time_ns, None, None, lambda model: model.event("marker", log_time_ns, text))
    kind, detail = str(body.get("kind", "event")), str(body.get("detail", ""))
    data_dict = body.get("data") if isinstance(body.get("data"), dict) else None
    return Item(log_time_ns, None, None, lambda model: model.event(kind, log_time_ns, detail, data_dict))


def read_items(path: Path, info: RecordingContents | None = None) -> Iterator[Item]:
    """The recording's received frames and ground-station records, in file order (a truncated file: up to the cut).

    Read with the bulk reader (iter_topic_data), not the mcap library's records: a window late in an hour reads
    the whole file, and building a record for each of its messages was most of `dive replay --from`'s time."""
    for topic, log_time_ns, data in iter_topic_data(path, TOPICS, info):
        item = _frame_item(log_time_ns, data) if topic == RAW_RX_TOPIC else record_item(topic, log_time_ns, data)
        if item is not None:
            yield item


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
