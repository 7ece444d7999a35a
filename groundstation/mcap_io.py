"""MCAP recordings (the one module importing mcap). PROVISIONAL reader for the view branch: the ground station
engineer's mcap_io.py (writer and reader) replaces this file when branch `groundstation` is merged."""

from __future__ import annotations

import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from mcap.exceptions import EndOfFile, InvalidMagic, McapError
from mcap.reader import NonSeekingReader

from groundstation.view_errors import ReplayError


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes


@dataclass
class ReadStatus:
    """Filled in while reading: whether the file ended before its footer (a crash cut it short)."""

    truncated: bool = False


def read_messages(path: Path, status: ReadStatus | None = None) -> Iterator[RecordedMessage]:
    """Every message in file order, streaming; a truncated file yields what is complete, then stops."""
    status = status if status is not None else ReadStatus()
    try:
        stream = path.open("rb")
    except OSError as e:
        raise ReplayError(f"cannot open {path}: {e.strerror or e}") from e
    with stream:
        try:
            for _schema, channel, message in NonSeekingReader(stream).iter_messages():
                yield RecordedMessage(channel.topic, message.log_time, message.publish_time, message.data)
        except InvalidMagic as e:
            raise ReplayError(f"{path} is not an MCAP file") from e
        except (EndOfFile, McapError, struct.error, ValueError, KeyError):
            status.truncated = True  # the recorder died mid-record: keep what was complete
