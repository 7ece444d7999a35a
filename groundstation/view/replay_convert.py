"""A replay converted at once: every item fed to one view model, its rows returned for columnar logging."""

from __future__ import annotations

from binascii import crc_hqx
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np

from groundstation.mcap_io import RecordingContents, iter_topic_data
from groundstation.recording.columns import record_dtype
from groundstation.recording.files import RecordingParts as Parts
from groundstation.view.model import Batch, ViewModel
from groundstation.view.replay_items import RAW_RX_TOPIC, TOPICS, Item, decode, header_items, record_item
from protocol import PROTOCOL_VERSION, FrameFlag
from protocol import messages as m
from protocol.crc import CRC_INIT
from protocol.enums import INCOMPATIBLE_FLAGS_MASK
from protocol.frame import MIN_INNER

_SAMPLE_ID = m.Sample.MSG_ID
_SAMPLE_SIZE = MIN_INNER + m.Sample.DEFINITION.fixed_size
_SAMPLE_DTYPE = record_dtype(m.Sample.DEFINITION)
_REPLAYED = int(FrameFlag.REPLAYED)
_UNCOMMON_FLAGS = INCOMPATIBLE_FLAGS_MASK | int(FrameFlag.SIGNED)  # such a frame takes the per-item path


def convert(items: Iterator[Item], progress: Callable[[int], None] | None = None) -> tuple[Batch, int]:
    """Feed everything to one model and return all its rows at once (for columnar logging) and the item count.

    Of the SAMPLEs before a window only the last before each other item is fed: the window keeps the state they
    leave (the last current cell, the timelines the next item's rows take, the count of backfilled ones), not
    their rows, and feeding each was most of a late window's time (`dive replay --from 150` of an hour)."""
    model = ViewModel()
    count, seen, before = 0, 0, False
    passed: Item | None = None  # the latest SAMPLE before the window, not fed yet
    for seen, item in enumerate(items, 1):  # noqa: B007
        if item.before:
            before = True
            if isinstance(item.message, m.Sample):
                if passed is not None and passed.flags & _REPLAYED:
                    model.count_backfilled()
                passed = item
                continue
        if passed is not None:
            passed.feed(model)
            passed = None
        if item.before:
            item.feed(model)
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


FIRST_SLICE_ITEMS = 8192  # a viewer fed in slices gets this many items first (a few minutes of a recording)


def convert_parts(parts: Parts, infos: list[RecordingContents], progress: Callable[[int], None] | None = None,
                  sink: Callable[[Batch], None] | None = None) -> tuple[Batch, int]:
    """convert_recording over every part into one model: one timeline, the view's state carried across parts.

    With `sink`, the rows are handed to it in slices as they are made, the first after FIRST_SLICE_ITEMS items and
    each next one twice as large: a viewer opens on the recording's first minutes while the rest is converted,
    instead of on nothing until the whole hour is (the rows and their order are the same; the last slice is
    returned)."""
    model = ViewModel()
    for item in header_items(parts):
        item.feed(model)
    count = 0
    slices = _Slices(model, sink) if sink is not None else None
    for path, info in zip(parts.files, infos, strict=True):
        count = _convert_into(model, path, info, progress, count, slices)
    return model.take(), count


class _Slices:
    """Hands the model's rows to a sink at growing item counts (FIRST_SLICE_ITEMS, then twice as many, ...)."""

    def __init__(self, model: ViewModel, sink: Callable[[Batch], None]) -> None:
        self._model, self._sink, self.next_at = model, sink, FIRST_SLICE_ITEMS

    def send(self, count: int) -> None:
        self._sink(self._model.take())
        self.next_at = 2 * count


def _convert_into(model: ViewModel, path: Path, info: RecordingContents | None = None,
                  progress: Callable[[int], None] | None = None, count: int = 0,
                  slices: _Slices | None = None) -> int:
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

    for topic, log_time_ns, data in iter_topic_data(path, TOPICS, info):
        if slices is not None and count >= slices.next_at:
            flush()
            slices.send(count)
        if topic == RAW_RX_TOPIC:
            if (len(data) == _SAMPLE_SIZE and data[4] == _SAMPLE_ID and data[0] == PROTOCOL_VERSION
                    and not data[1] & _UNCOMMON_FLAGS and not crc_hqx(data, CRC_INIT)):
                inners.append(data)
                times.append(log_time_ns)
                count += 1
                continue
            decoded = decode(data)
            if decoded is None:
                continue
            count += 1
            if not isinstance(decoded[0], ViewModel.SHOWN):  # HEARTBEAT, ACK...: no rows, no state; the run goes on
                continue
            flush()
            model.feed(decoded[0], log_time_ns, flags=decoded[1])
        else:
            flush()
            item = record_item(topic, log_time_ns, data)
            if item is not None:
                item.feed(model)
                count += 1
        if progress is not None and count % 4096 == 0:
            progress(count)
    flush()
    return count
