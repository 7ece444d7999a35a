"""MCAP files: a crash-safe writer and a reader that tolerates truncation. The only module importing `mcap`."""

from __future__ import annotations

import io
import json
import os
import struct
import time
import zlib
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from io import BytesIO
from itertools import chain
from pathlib import Path
from types import TracebackType
from typing import IO, Any, Self

import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, Message, MessageIndex, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, Writer

from groundstation.errors import RecordingError, RecordingExistsError, RecordingTooLargeError

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
    damaged_chunks: int = 0  # chunks skipped because their data was damaged (the rest of the file was read)


# Untrusted sizes (issue 13 item 1): a file's records can claim any length. No record is read past the end of the
# file, no chunk decompresses to more than it declares, and a file's chunks together decompress to at most
# DECODED_PER_DISK_BYTE times its size on disk (our recordings: 5-10x; see docs/reliability.md) or
# DECODED_FLOOR_BYTES, whichever is larger; past that the read stops with RecordingTooLargeError.
DECODED_PER_DISK_BYTE = 64
DECODED_FLOOR_BYTES = 64 * 1024 * 1024


class _BoundedFile:
    """A binary file whose read(n) never asks for more than is left: a huge length allocates nothing."""

    def __init__(self, stream: IO[bytes], size: int) -> None:
        self._stream, self._size = stream, size

    def read(self, n: int = -1) -> bytes:
        left = max(0, self._size - self._stream.tell())
        return self._stream.read(left if n < 0 else min(n, left))


def _chunk_data(chunk: Chunk, budget: list[int], path: Path) -> bytes | None:
    """A chunk's data, decompressed within its declared size and the file's budget; None if it is damaged."""
    if chunk.uncompressed_size > budget[0]:
        raise RecordingTooLargeError(
            f"{path}: its chunks claim more than {DECODED_PER_DISK_BYTE} times the file's size when decompressed "
            "(a damaged or hostile file); not read further")
    if chunk.compression == "zstd":
        with zstandard.ZstdDecompressor().stream_reader(chunk.data) as reader:
            data = reader.read(chunk.uncompressed_size + 1)
    elif chunk.compression == "":
        data = chunk.data
    else:
        return None
    budget[0] -= len(data)
    if len(data) != chunk.uncompressed_size or (chunk.uncompressed_crc and zlib.crc32(data) != chunk.uncompressed_crc):
        return None
    return bytes(data)


def _chunk_records(chunk: Chunk, budget: list[int], path: Path) -> list[Any]:
    """A chunk's records, decompressed within its declared size and the file's budget; [] if it is damaged."""
    data = _chunk_data(chunk, budget, path)
    if data is None:
        return []
    return breakup_chunk(Chunk(compression="", data=data, message_end_time=chunk.message_end_time,
                               message_start_time=chunk.message_start_time, uncompressed_crc=0,
                               uncompressed_size=len(data)))


class _ChunkData(bytes):
    """A chunk's decompressed, checked data, not broken up into records (for iter_topic_data)."""


class _Reader(StreamReader):
    """The mcap stream reader without the message indexes: no reader of ours uses them, and parsing one
    costs two calls per message it indexes (half of reading a long recording)."""

    def _read_record(self, opcode: int, length: int) -> Any:
        if opcode == Opcode.MESSAGE_INDEX:
            self._stream.read(length)
            return None
        return super()._read_record(opcode, length)


def _records(path: Path, damaged: list[int] | None = None, chunk_data: bool = False) -> Iterator[Any]:
    """Every record in file order; stops quietly at a truncated or corrupt tail (raises _Truncated after).

    A chunk whose data is damaged (CRC, decompression) is skipped and counted in damaged[0]; the records after it
    are read on (issue 13 item 5: one flipped bit loses one chunk, not the rest of the file). With chunk_data, a
    chunk comes as its data (_ChunkData) instead of its records.
    """
    try:
        stream = open(path, "rb")  # noqa: SIM115
        size = os.fstat(stream.fileno()).st_size
    except FileNotFoundError as e:
        raise RecordingError(f"no such recording: {path}") from e
    except OSError as e:
        raise RecordingError(f"cannot read {path}: {e.strerror or e}") from e
    budget = [max(DECODED_FLOOR_BYTES, DECODED_PER_DISK_BYTE * size)]
    with stream:
        try:
            reader = _Reader(_BoundedFile(stream, size), skip_magic=False, emit_chunks=True,  # type: ignore[arg-type]
                             record_size_limit=size)
            for record in reader.records:
                if not isinstance(record, Chunk):
                    yield record
                    continue
                try:
                    if chunk_data:
                        data = _chunk_data(record, budget, path)
                        inner: list[Any] = [] if data is None else [_ChunkData(data)]
                    else:
                        inner = _chunk_records(record, budget, path)
                except (zstandard.ZstdError, McapError, EOFError, ValueError, KeyError, IndexError, struct.error):
                    inner = []
                if not inner and record.uncompressed_size:
                    if damaged is not None:
                        damaged[0] += 1
                    continue
                yield from inner
        except RecordingTooLargeError:
            raise
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
    damaged = [0]
    for record in _summary_channels(path):  # a damaged chunk may have held a channel later chunks use
        if isinstance(record, Schema):
            schemas[record.id] = record
        else:
            channels[record.id] = record
    try:
        for record in _records(path, damaged):
            seen += 1
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                channels[record.id] = record
                schema = schemas.get(record.schema_id)
                if schema is not None and schema.encoding == JSONSCHEMA:
                    try:
                        info.schemas[record.topic] = json.loads(schema.data)
                    except ValueError:
                        pass  # a schema that is not JSON: the messages are still readable
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
    finally:
        info.damaged_chunks = damaged[0]


_FOOTER_BYTES = 1 + 8 + 8 + 8 + 4  # opcode, length, summary_start, summary_offset_start, summary_crc


def _summary_channels(path: Path) -> list[Schema | Channel]:
    """The schemas and channels of a finished file's summary section (after its footer's pointer); [] if none."""
    try:
        with open(path, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            if size < len(MAGIC) * 2 + _FOOTER_BYTES:
                return []
            stream.seek(size - len(MAGIC) - _FOOTER_BYTES)
            footer = stream.read(_FOOTER_BYTES)
            if footer[0] != 0x02 or stream.read(len(MAGIC)) != MAGIC:
                return []
            summary_start = struct.unpack_from("<Q", footer, 9)[0]
            end = size - len(MAGIC) - _FOOTER_BYTES
            if not len(MAGIC) <= summary_start < end:
                return []
            stream.seek(summary_start)
            section = stream.read(end - summary_start)
        found: list[Schema | Channel] = []
        view = memoryview(section)
        offset = 0
        while offset + 9 <= len(view):
            opcode, length = view[offset], struct.unpack_from("<Q", view, offset + 1)[0]
            body = bytes(view[offset + 9: offset + 9 + length])
            offset += 9 + length
            if opcode in (0x03, 0x04) and len(body) == length:
                record = (Schema if opcode == 0x03 else Channel).read(ReadDataStream(io.BytesIO(body)))
                found.append(record)
        return found
    except Exception:  # noqa: BLE001 a damaged summary only means the stream's own channel records are used
        return []


_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length
_MESSAGE_FIXED = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time


def iter_topic_data(path: Path, topics: set[str],
                    info: RecordingContents | None = None) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time, data) of the messages of `topics`, in file order: iter_messages for bulk reads.

    The mcap reader builds a record object for every message of the file, the hundreds of thousands of
    an hour's JSON copies too; this walks each chunk's data with one struct call per record and builds
    nothing for messages of other topics. The same tolerance of truncated and damaged files, the same `info`.
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
                try:
                    info.schemas[record.topic] = json.loads(schema.data)
                except ValueError:
                    pass  # a schema that is not JSON: the messages are still readable

    for record in _summary_channels(path):  # a damaged chunk may have held a channel later chunks use
        known(record)
    seen = 0
    damaged = [0]
    try:
        for record in _records(path, damaged, chunk_data=True):
            seen += 1
            if isinstance(record, _ChunkData):
                size = len(record)
                at = 0
                try:
                    while at < size:
                        opcode, length = _RECORD_HEAD.unpack_from(record, at)
                        start = at + 9
                        at = start + length
                        if opcode == Opcode.MESSAGE:
                            channel_id, _, log_time, _ = _MESSAGE_FIXED.unpack_from(record, start)
                            topic = wanted.get(channel_id)
                            if topic is not None:
                                yield topic, log_time, record[start + 22 : at]
                        elif opcode == Opcode.SCHEMA:
                            known(Schema.read(ReadDataStream(BytesIO(record[start:at]))))
                        elif opcode == Opcode.CHANNEL:
                            known(Channel.read(ReadDataStream(BytesIO(record[start:at]))))
                except (struct.error, McapError, ValueError, EOFError, KeyError, IndexError):
                    damaged[0] += 1  # a chunk that passed its CRC yet does not parse: its messages so far stand
            elif isinstance(record, Message):
                topic = wanted.get(record.channel_id)
                if topic is not None:
                    yield topic, record.log_time, bytes(record.data)
            elif isinstance(record, Metadata):
                info.metadata.setdefault(record.name, []).append(dict(record.metadata))
            elif isinstance(record, Attachment):
                info.attachments.append((record.name, bytes(record.data)))
            else:
                known(record)
    except _Truncated:
        info.truncated = True
        if seen == 0:
            raise RecordingError(f"{path} is not an MCAP recording") from None
    finally:
        info.damaged_chunks = damaged[0]


def read_header(path: Path) -> dict[str, list[dict[str, str]]]:
    """The metadata a file begins with, read up to its first message: the recorder writes the session header
    (agent_hello, host, session, parameters) before anything else. RecordingError if the file is missing or
    not an MCAP recording."""
    metadata: dict[str, list[dict[str, str]]] = {}
    seen = 0
    try:
        for record in _records(path):
            seen += 1
            if isinstance(record, Metadata):
                metadata.setdefault(record.name, []).append(dict(record.metadata))
            elif isinstance(record, Message):
                break
    except _Truncated:
        if seen == 0:
            raise RecordingError(f"{path} is not an MCAP recording") from None
    return metadata


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
