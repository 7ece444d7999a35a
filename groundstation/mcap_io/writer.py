"""Writing MCAP recordings: a crash-safe writer whose hot path writes a frame's two records in one call."""

from __future__ import annotations

import json
import os
import struct
import time
from collections.abc import Callable
from io import BytesIO
from itertools import chain
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Self

from mcap.opcode import Opcode
from mcap.records import MessageIndex
from mcap.writer import CompressionType, Writer

from groundstation.errors import RecordingError, RecordingExistsError

PROFILE = "diving-agent"
JSON = "json"
JSONSCHEMA = "jsonschema"
RAW_ENCODING = "diving-agent-frame-v1"
MAGIC = b"\x89MCAP0\r\n"


def mcap_library_version() -> str:
    from importlib.metadata import version

    return version("mcap")


class McapFileWriter:
    """One MCAP file. Chunks are closed and the file flushed and fsynced every `flush_period_s`,
    so a killed process loses at most that much and leaves a file `RecordingReader` reads.

    The mcap Writer has no context manager: this one has, and close() always runs finish().
    """

    def __init__(self, path: Path, flush_period_s: float = 1.0) -> None:
        self.path = path
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            # "x": never replaces a file (issue 13: no command destroys a recording); callers pick a free name
            self._file: IO[bytes] = open(path, "xb")  # noqa: SIM115 closed in close()
        except FileExistsError as e:
            raise RecordingExistsError(f"{path} exists; a recording is never overwritten: give another name") from e
        except OSError as e:
            raise RecordingError(f"cannot write {path}: {e.strerror or e}") from e
        self._writer = Writer(self._file, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library=f"dive (mcap {mcap_library_version()})")
        self._file.flush()  # the magic and header on disk at once: a kill in the first second leaves no 0-byte file
        self._add, self._add_pair = _message_adders(self._writer)
        self._pending = _pending_chunk_bytes(self._writer)
        self._schemas: dict[str, int] = {}
        self._summary_bytes = 0  # what close() writes again after the data: schemas and channels (size_on_disk)
        self._channels: dict[str, int] = {}
        self._flush_period_s = flush_period_s
        self._last_flush_s = time.monotonic()
        self._closed = False
        self.bytes_written = 0
        self.messages = 0

    def channel(self, topic: str, encoding: str = JSON, schema_name: str = "",
                schema: dict[str, Any] | None = None) -> int:
        channel_id = self._channels.get(topic)
        if channel_id is None:
            schema_id = 0
            if schema is not None:
                schema_id = self._schemas.get(schema_name, 0)
                if not schema_id:
                    data = json.dumps(schema).encode()
                    schema_id = self._writer.register_schema(schema_name, JSONSCHEMA, data)
                    self._schemas[schema_name] = schema_id
                    self._summary_bytes += len(data) + len(schema_name) + _SUMMARY_RECORD_BYTES
            channel_id = self._writer.register_channel(topic, encoding, schema_id)
            self._channels[topic] = channel_id
            self._summary_bytes += len(topic) + _SUMMARY_RECORD_BYTES
        return channel_id

    def has_channel(self, topic: str) -> bool:
        return topic in self._channels

    def write(self, channel_id: int, data: bytes, log_time_ns: int, publish_time_ns: int | None = None) -> None:
        self.write_many(((channel_id, data),), log_time_ns, publish_time_ns)

    def write_many(self, messages: tuple[tuple[int, bytes], ...], log_time_ns: int,
                   publish_time_ns: int | None = None) -> None:
        """Several messages of the same times (a frame's JSON body and its raw bytes): one call, one flush check."""
        self._add(messages, log_time_ns, log_time_ns if publish_time_ns is None else publish_time_ns)
        written = 0
        for _, data in messages:
            written += len(data) + 40
        self.bytes_written += written
        self.messages += len(messages)
        if time.monotonic() - self._last_flush_s >= self._flush_period_s:  # maybe_flush, inlined: once per frame
            self.flush()

    def write_frame(self, channel_id: int, data: bytes, raw_channel_id: int, raw: bytes, log_time_ns: int,
                    publish_time_ns: int | None = None) -> None:
        """write_many of a frame's two messages (JSON body, raw bytes) without building tuples: every frame's path."""
        self._add_pair(channel_id, data, raw_channel_id, raw, log_time_ns,
                       log_time_ns if publish_time_ns is None else publish_time_ns)
        self.bytes_written += len(data) + len(raw) + 80  # as write_many counts them
        self.messages += 2
        if time.monotonic() - self._last_flush_s >= self._flush_period_s:
            self.flush()

    def size_on_disk(self) -> int:
        """About the bytes this file holds on disk once closed (`dive run --split-mb` counts disk, not messages):
        what was handed to the file, the chunk being built compressed as well as the chunks before it were, and
        the summary close() adds (the schemas and channels again, an index entry per chunk: ~1 % of the data).
        """
        handed = self._file.tell()
        pending = self._pending()
        flushed = self.bytes_written - pending
        # Before the first chunk is on disk, zstd's ratio on our JSON and raw frames is unknown: assume 1/4 (the
        # recordings measured 5-10x), so a small split size is not overshot by the whole first chunk.
        ratio = (handed / flushed) if flushed >= _RATIO_KNOWN_BYTES else 0.25
        data = handed + int(pending * min(ratio, 1.0))
        return data + self._summary_bytes + data // 100

    def metadata(self, name: str, values: dict[str, Any]) -> None:
        self._writer.add_metadata(name, {k: v if isinstance(v, str) else json.dumps(v) for k, v in values.items()})

    def attachment(self, name: str, data: bytes, media_type: str = "application/json") -> None:
        now = time.time_ns()
        self._writer.add_attachment(now, now, name, media_type, data)

    def maybe_flush(self) -> None:
        if time.monotonic() - self._last_flush_s >= self._flush_period_s:
            self.flush()

    def flush(self) -> None:
        self._last_flush_s = time.monotonic()
        self._writer.flush()  # closes the chunk in progress
        try:
            os.fsync(self._file.fileno())
        except OSError:
            pass

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            self._writer.finish()
        finally:
            self._file.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


_MESSAGE_HEAD = struct.Struct("<BQHIQQ")  # opcode, record length, channel id, sequence, log time, publish time
_MESSAGE_FIELDS = _MESSAGE_HEAD.size - 9  # the record length counts what follows the opcode and the length


class _MessageIndex(MessageIndex):
    """A chunk's message index written in one piece (MessageIndex.write makes two small writes per message)."""

    def write(self, stream: Any) -> None:
        records = self.records
        stream.write(struct.pack(f"<BQHI{2 * len(records)}Q", Opcode.MESSAGE_INDEX, 6 + 16 * len(records),
                                 self.channel_id, 16 * len(records), *chain.from_iterable(records)))


_SUMMARY_RECORD_BYTES = 64  # a schema or channel record's fixed fields and its index entry, about
_RATIO_KNOWN_BYTES = 64 * 1024  # message bytes on disk before their compression ratio is taken as known


def _pending_chunk_bytes(writer: Writer) -> Callable[[], int]:
    """The uncompressed bytes of the chunk the Writer is building (the same internals _message_adders uses);
    always 0 if this mcap version lays its Writer out differently (the size on disk is then a chunk low)."""
    builder = getattr(writer, "_Writer__chunk_builder", None)

    def pending() -> int:
        buffer = getattr(getattr(builder, "record_writer", None), "_buffer", None)
        return buffer.tell() if isinstance(buffer, BytesIO) else 0

    return pending


_Adder = Callable[[tuple[tuple[int, bytes], ...], int, int], None]
_PairAdder = Callable[[int, bytes, int, bytes, int, int], None]


def _message_adders(writer: Writer) -> tuple[_Adder, _PairAdder]:
    """`add(((channel_id, data), ...), log_time, publish_time)`: what Writer.add_message does for each message,
    and `add_pair(channel_id, data, channel_id, data, log_time, publish_time)`, the same for two messages.

    Writer.add_message builds a Message record object and writes it field by field (eight small writes
    and two seeks), more than a frame costs us to decode and encode as JSON; a recorder writes two per
    frame. This does the same bookkeeping (statistics, the chunk's message index and times) on the
    Writer's own chunk builder and writes each record (and the chunk's message index) in one piece;
    a test checks the file is byte for
    byte the one add_message writes. Falls back to add_message if this mcap version's Writer is laid out
    differently (chunking off, or renamed internals).
    """
    statistics = getattr(writer, "_Writer__statistics", None)
    builder = getattr(writer, "_Writer__chunk_builder", None)
    finalize = getattr(writer, "_Writer__finalize_chunk", None)
    chunk_size = getattr(writer, "_Writer__chunk_size", None)
    records = getattr(builder, "record_writer", None)
    if (statistics is None or finalize is None or not isinstance(chunk_size, int)
            or not isinstance(getattr(records, "_buffer", None), BytesIO)):
        def add_messages(messages: tuple[tuple[int, bytes], ...], log_time: int, publish_time: int) -> None:
            for channel_id, data in messages:
                writer.add_message(channel_id, log_time=log_time, data=data, publish_time=publish_time)

        def add_two(first: int, data: bytes, second: int, raw: bytes, log_time: int, publish_time: int) -> None:
            add_messages(((first, data), (second, raw)), log_time, publish_time)
        return add_messages, add_two
    assert builder is not None and records is not None
    channel_counts = statistics.channel_message_counts
    indices = builder.message_indices
    pack = _MESSAGE_HEAD.pack

    head_size = _MESSAGE_HEAD.size
    message_op = int(Opcode.MESSAGE)  # an IntEnum member costs struct.pack a call to __index__

    def add_each(messages: tuple[tuple[int, bytes], ...], log_time: int, publish_time: int) -> None:
        """Message by message, closing the chunk as soon as it is full (as add_message does)."""
        stats = statistics
        chunk = builder
        buffer = records._buffer  # a new BytesIO after every chunk
        for channel_id, data in messages:
            if log_time < stats.message_start_time or stats.message_count == 0:
                stats.message_start_time = log_time
            if log_time > stats.message_end_time:
                stats.message_end_time = log_time
            channel_counts[channel_id] += 1
            stats.message_count += 1
            if log_time < chunk.message_start_time or chunk.num_messages == 0:
                chunk.message_start_time = log_time
            if log_time > chunk.message_end_time:
                chunk.message_end_time = log_time
            index = indices.get(channel_id)
            if index is None:
                index = indices[channel_id] = _MessageIndex(channel_id=channel_id, records=[])
            position = buffer.tell()
            index.records.append((log_time, position))
            chunk.num_messages += 1
            buffer.write(pack(Opcode.MESSAGE, _MESSAGE_FIELDS + len(data), channel_id, 0, log_time, publish_time))
            buffer.write(data)
            if position + head_size + len(data) > chunk_size:  # Writer.__maybe_finalize_chunk
                finalize()
                buffer = records._buffer

    def add(messages: tuple[tuple[int, bytes], ...], log_time: int, publish_time: int) -> None:
        """A frame's two messages (its JSON body and its raw bytes) with the bookkeeping done once, one write.

        The result is add_each's: both have the same times, so the start and end times can change only at the
        first; a chunk that fills at the first goes through add_each, which closes it in between.
        """
        if len(messages) != 2:
            add_each(messages, log_time, publish_time)
            return
        (first, data), (second, raw) = messages
        add_pair(first, data, second, raw, log_time, publish_time)

    def add_pair(first: int, data: bytes, second: int, raw: bytes, log_time: int, publish_time: int) -> None:
        buffer = records._buffer
        position = buffer.tell()
        data_size, raw_size = len(data), len(raw)
        middle = position + head_size + data_size
        if middle > chunk_size:
            add_each(((first, data), (second, raw)), log_time, publish_time)
            return
        stats = statistics
        chunk = builder
        count = stats.message_count
        if log_time < stats.message_start_time or count == 0:
            stats.message_start_time = log_time
        if log_time > stats.message_end_time:
            stats.message_end_time = log_time
        stats.message_count = count + 2
        count = chunk.num_messages
        if log_time < chunk.message_start_time or count == 0:
            chunk.message_start_time = log_time
        if log_time > chunk.message_end_time:
            chunk.message_end_time = log_time
        chunk.num_messages = count + 2
        channel_counts[first] += 1
        channel_counts[second] += 1
        try:  # after the first frame of a chunk both channels have their index
            indices[first].records.append((log_time, position))
        except KeyError:
            indices[first] = _MessageIndex(channel_id=first, records=[(log_time, position)])
        try:
            indices[second].records.append((log_time, middle))
        except KeyError:
            indices[second] = _MessageIndex(channel_id=second, records=[(log_time, middle)])
        buffer.write(b"".join((pack(message_op, _MESSAGE_FIELDS + data_size, first, 0, log_time, publish_time), data,
                               pack(message_op, _MESSAGE_FIELDS + raw_size, second, 0, log_time, publish_time), raw)))
        if middle + head_size + raw_size > chunk_size:
            finalize()

    return add, add_pair
