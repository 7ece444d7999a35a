"""MCAP files: a crash-safe writer and a reader that tolerates truncation. The only module importing `mcap`."""

from __future__ import annotations

import json
import os
import struct
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from io import BytesIO
from itertools import chain
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Self

from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import StreamReader, get_chunk_data_stream
from mcap.writer import CompressionType, Writer

from groundstation.errors import RecordingError

PROFILE = "diving-agent"
JSON = "json"
JSONSCHEMA = "jsonschema"
RAW_ENCODING = "diving-agent-frame-v1"


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
            self._file: IO[bytes] = open(path, "wb")  # noqa: SIM115 closed in close()
        except OSError as e:
            raise RecordingError(f"cannot write {path}: {e.strerror or e}") from e
        self._writer = Writer(self._file, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
        self._writer.start(profile=PROFILE, library=f"dive (mcap {mcap_library_version()})")
        self._add = _message_adder(self._writer)
        self._schemas: dict[str, int] = {}
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
                    schema_id = self._writer.register_schema(schema_name, JSONSCHEMA, json.dumps(schema).encode())
                    self._schemas[schema_name] = schema_id
            channel_id = self._writer.register_channel(topic, encoding, schema_id)
            self._channels[topic] = channel_id
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


_Adder = Callable[[tuple[tuple[int, bytes], ...], int, int], None]


def _message_adder(writer: Writer) -> _Adder:
    """`add(((channel_id, data), ...), log_time, publish_time)`: what Writer.add_message does for each message.

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
        return add_messages
    assert builder is not None and records is not None
    channel_counts = statistics.channel_message_counts
    indices = builder.message_indices
    pack = _MESSAGE_HEAD.pack

    def add(messages: tuple[tuple[int, bytes], ...], log_time: int, publish_time: int) -> None:
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
            if position + _MESSAGE_HEAD.size + len(data) > chunk_size:  # Writer.__maybe_finalize_chunk
                finalize()
                buffer = records._buffer

    return add


@dataclass(frozen=True, slots=True)
class RecordedMessage:
    topic: str
    log_time_ns: int
    publish_time_ns: int
    data: bytes
    encoding: str
    schema_name: str

    def json(self) -> Any:
        return json.loads(self.data)


@dataclass
class RecordingContents:
    """Everything a tolerant read found; `truncated` says the file ended early (crash, copy cut short)."""

    messages: list[RecordedMessage] = field(default_factory=list)
    metadata: dict[str, list[dict[str, str]]] = field(default_factory=dict)
    schemas: dict[str, dict[str, Any]] = field(default_factory=dict)  # topic -> JSON schema
    attachments: list[tuple[str, bytes]] = field(default_factory=list)
    truncated: bool = False


def _records(path: Path, emit_chunks: bool = False) -> Iterator[Any]:
    """Every record in file order; stops quietly at a truncated or corrupt tail (raises _Truncated after).

    With emit_chunks, chunks come whole (Chunk records) instead of as the records they hold.
    """
    try:
        stream = open(path, "rb")  # noqa: SIM115
    except FileNotFoundError as e:
        raise RecordingError(f"no such recording: {path}") from e
    except OSError as e:
        raise RecordingError(f"cannot read {path}: {e.strerror or e}") from e
    with stream:
        try:
            yield from StreamReader(stream, skip_magic=False, validate_crcs=True, emit_chunks=emit_chunks).records
        except (McapError, EOFError, ValueError, KeyError, IndexError, OSError) as e:
            if isinstance(e, OSError):
                raise RecordingError(f"cannot read {path}: {e}") from e
            raise _Truncated(str(e)) from e
        except Exception as e:  # noqa: BLE001 a damaged tail can break the parser in many ways
            raise _Truncated(str(e)) from e


class _Truncated(Exception):
    pass


def iter_messages(path: Path, topics: set[str] | None = None,
                  info: RecordingContents | None = None) -> Iterator[RecordedMessage]:
    """Messages in file order (optionally only some topics). Fills `info` with metadata and schemas."""
    info = info if info is not None else RecordingContents()
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    seen = 0
    try:
        for record in _records(path):
            seen += 1
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
                schema = schemas.get(record.schema_id)
                if schema is not None and schema.encoding == JSONSCHEMA:
                    info.schemas[record.topic] = json.loads(schema.data)
            elif isinstance(record, Message):
                channel = channels.get(record.channel_id)
                if channel is None or (topics is not None and channel.topic not in topics):
                    continue
                schema = schemas.get(channel.schema_id)
                yield RecordedMessage(channel.topic, record.log_time, record.publish_time, bytes(record.data),
                                      channel.message_encoding, schema.name if schema else "")
            elif isinstance(record, Metadata):
                info.metadata.setdefault(record.name, []).append(dict(record.metadata))
            elif isinstance(record, Attachment):
                info.attachments.append((record.name, bytes(record.data)))
    except _Truncated:
        info.truncated = True
        if seen == 0:
            raise RecordingError(f"{path} is not an MCAP recording") from None


_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length
_MESSAGE_FIXED = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time


def iter_topic_data(path: Path, topics: set[str],
                    info: RecordingContents | None = None) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time, data) of the messages of `topics`, in file order: iter_messages for bulk reads.

    The mcap reader builds a record object for every message of the file, the hundreds of thousands of
    an hour's JSON copies too; this decompresses each chunk and walks its records with one struct call
    each, building nothing for messages of other topics. Same tolerance of a truncated file, same `info`.
    """
    info = info if info is not None else RecordingContents()
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    wanted: dict[int, str] = {}

    def known(record: Any) -> None:
        if isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record
            if record.topic in topics:
                wanted[record.id] = record.topic
            schema = schemas.get(record.schema_id)
            if schema is not None and schema.encoding == JSONSCHEMA:
                info.schemas[record.topic] = json.loads(schema.data)

    try:
        stream = open(path, "rb")  # noqa: SIM115
    except FileNotFoundError as e:
        raise RecordingError(f"no such recording: {path}") from e
    except OSError as e:
        raise RecordingError(f"cannot read {path}: {e.strerror or e}") from e
    with stream:
        if stream.read(len(MCAP_MAGIC)) != MCAP_MAGIC:
            raise RecordingError(f"{path} is not an MCAP recording")
        while True:
            head = stream.read(9)
            if len(head) < 9:
                info.truncated = True  # no footer: cut short
                return
            opcode, length = _RECORD_HEAD.unpack(head)
            body = stream.read(length)
            if len(body) < length:
                info.truncated = True
                return
            if opcode == Opcode.FOOTER:
                return
            if opcode == Opcode.MESSAGE:  # outside a chunk (files written without chunking)
                channel_id, _, log_time, _ = _MESSAGE_FIXED.unpack_from(body)
                topic = wanted.get(channel_id)
                if topic is not None:
                    yield topic, log_time, body[22:]
                continue
            if opcode not in _READ_OPCODES:
                continue  # indexes, statistics, summary: nothing a reader of topics needs
            try:
                record = _READ_OPCODES[opcode].read(ReadDataStream(BytesIO(body)))
                if isinstance(record, Chunk):
                    chunk_stream, size = get_chunk_data_stream(record, validate_crc=True)
                    data = chunk_stream.read(size)
                    at = 0
                    while at < size:
                        inner_opcode, inner_length = _RECORD_HEAD.unpack_from(data, at)
                        start = at + 9
                        at = start + inner_length
                        if inner_opcode == Opcode.MESSAGE:
                            channel_id, _, log_time, _ = _MESSAGE_FIXED.unpack_from(data, start)
                            topic = wanted.get(channel_id)
                            if topic is not None:
                                yield topic, log_time, data[start + 22 : at]
                        elif inner_opcode in (Opcode.SCHEMA, Opcode.CHANNEL):
                            known(_READ_OPCODES[inner_opcode].read(ReadDataStream(BytesIO(data[start:at]))))
                elif isinstance(record, Metadata):
                    info.metadata.setdefault(record.name, []).append(dict(record.metadata))
                elif isinstance(record, Attachment):
                    info.attachments.append((record.name, bytes(record.data)))
                else:
                    known(record)
            except (struct.error, McapError, ValueError, EOFError, KeyError, IndexError):
                info.truncated = True  # a damaged record: what came before it stands
                return


MCAP_MAGIC = b"\x89MCAP0\r\n"
_READ_OPCODES: dict[int, Any] = {Opcode.SCHEMA: Schema, Opcode.CHANNEL: Channel, Opcode.CHUNK: Chunk,
                                 Opcode.METADATA: Metadata, Opcode.ATTACHMENT: Attachment}


def read_recording(path: Path, topics: set[str] | None = None) -> RecordingContents:
    info = RecordingContents()
    info.messages = list(iter_messages(path, topics, info))
    return info


def is_complete(path: Path) -> bool:
    """True if the file ends with a footer (it was finished, not cut short)."""
    info = RecordingContents()
    for _ in iter_messages(path, set(), info):
        pass
    return not info.truncated


def recover(source: Path, target: Path) -> tuple[int, bool]:
    """Rewrite a (possibly truncated) recording into a finished, indexed one; (messages copied, was truncated)."""
    info = RecordingContents()
    count = 0
    with McapFileWriter(target, flush_period_s=3600) as out:
        for msg in iter_messages(source, None, info):
            channel_id = out.channel(msg.topic, msg.encoding, msg.schema_name, info.schemas.get(msg.topic))
            out.write(channel_id, msg.data, msg.log_time_ns, msg.publish_time_ns)
            count += 1
        for name, entries in info.metadata.items():
            for entry in entries:
                out.metadata(name, entry)
        for name, data in info.attachments:
            out.attachment(name, data)
    return count, info.truncated
