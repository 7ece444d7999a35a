"""Reading MCAP recordings: bounded against hostile sizes, tolerant of truncation and damaged chunks."""

from __future__ import annotations

import json
import os
import struct
import zlib
from collections.abc import Iterator
from dataclasses import dataclass, field
from io import BytesIO
from pathlib import Path
from typing import IO, Any

import zstandard
from mcap.data_stream import ReadDataStream
from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.records import Attachment, Channel, Chunk, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk

from groundstation.errors import RecordingError, RecordingTooLargeError
from groundstation.mcap_io.writer import JSONSCHEMA, MAGIC, McapFileWriter


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
    return decompress_chunk(chunk.compression, chunk.data, chunk.uncompressed_size, chunk.uncompressed_crc,
                            budget, path)


def decompress_chunk(compression: str, data: bytes, uncompressed_size: int, uncompressed_crc: int,
                     budget: list[int], path: Path) -> bytes | None:
    """Chunk data decompressed within its declared size and the file's budget (budget[0] bytes left, lowered by
    what this takes); None if it is damaged. RecordingTooLargeError when the declared size exceeds the budget."""
    if uncompressed_size > budget[0]:
        raise RecordingTooLargeError(
            f"{path}: its chunks claim more than {DECODED_PER_DISK_BYTE} times the file's size when decompressed "
            "(a damaged or hostile file); not read further")
    if compression == "zstd":
        with zstandard.ZstdDecompressor().stream_reader(data) as reader:
            out = reader.read(uncompressed_size + 1)
    elif compression == "":
        out = data
    else:
        return None
    budget[0] -= len(out)
    if len(out) != uncompressed_size or (uncompressed_crc and zlib.crc32(out) != uncompressed_crc):
        return None
    return bytes(out)


def decode_budget(size: int) -> list[int]:
    """The bytes a file of `size` bytes may decompress to in all (see DECODED_PER_DISK_BYTE), as a mutable cell."""
    return [max(DECODED_FLOOR_BYTES, DECODED_PER_DISK_BYTE * size)]


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
    budget = decode_budget(size)
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


def _filling(info: RecordingContents, path: Path, damaged: list[int], chunk_data: bool = False) -> Iterator[Any]:
    """_records for the readers that fill `info`: metadata and attachments go into it and are not yielded;
    at the end (or when the reader is closed) `info` says whether the file was truncated and how many chunks
    were damaged (damaged[0], which the caller may add to). A file with no record at all is no recording."""
    seen = 0
    try:
        for record in _records(path, damaged, chunk_data):
            seen += 1
            if isinstance(record, Metadata):
                info.metadata.setdefault(record.name, []).append(dict(record.metadata))
            elif isinstance(record, Attachment):
                info.attachments.append((record.name, bytes(record.data)))
            else:
                yield record
    except _Truncated:
        info.truncated = True
        if seen == 0:
            raise RecordingError(f"{path} is not an MCAP recording") from None
    finally:
        info.damaged_chunks = damaged[0]


class _Catalog:
    """The schemas and channels a reader has met, starting with the summary's (a damaged chunk may have held a
    channel later chunks use); each channel's JSON Schema goes into `info`, and the ids of `topics` into wanted."""

    def __init__(self, path: Path, info: RecordingContents, topics: set[str] | None = None) -> None:
        self.schemas: dict[int, Schema] = {}
        self.channels: dict[int, Channel] = {}
        self.wanted: dict[int, str] = {}
        self._info, self._topics = info, topics
        for record in _summary_channels(path):
            self.add(record)

    def add(self, record: Any) -> bool:
        """Takes a Schema or Channel record; False for any other record."""
        if isinstance(record, Schema):
            self.schemas[record.id] = record
            return True
        if not isinstance(record, Channel):
            return False
        self.channels[record.id] = record
        if self._topics is not None and record.topic in self._topics:
            self.wanted[record.id] = record.topic
        schema = self.schemas.get(record.schema_id)
        if schema is not None and schema.encoding == JSONSCHEMA:
            try:
                self._info.schemas[record.topic] = json.loads(schema.data)
            except ValueError:
                pass  # a schema that is not JSON: the messages are still readable
        return True


def iter_messages(path: Path, topics: set[str] | None = None,
                  info: RecordingContents | None = None) -> Iterator[RecordedMessage]:
    """Messages in file order (optionally only some topics). Fills `info` with metadata and schemas."""
    info = info if info is not None else RecordingContents()
    catalog = _Catalog(path, info)
    schemas, channels = catalog.schemas, catalog.channels
    for record in _filling(info, path, [0]):
        if catalog.add(record):
            continue
        if isinstance(record, Message):
            channel = channels.get(record.channel_id)
            if channel is None or (topics is not None and channel.topic not in topics):
                continue
            schema = schemas.get(channel.schema_id)
            yield RecordedMessage(channel.topic, record.log_time, record.publish_time, bytes(record.data),
                                  channel.message_encoding, schema.name if schema else "")


_RECORD_HEAD = struct.Struct("<BQ")  # opcode, length
_MESSAGE_FIXED = struct.Struct("<HIQQ")  # channel id, sequence, log time, publish time
_CATALOG_RECORDS = (Opcode.SCHEMA, Opcode.CHANNEL)


def _raw_records(data: bytes) -> Iterator[tuple[int, int, int]]:
    """(opcode, body start, body end) of each record in a run of records (a summary section, a chunk's data),
    without parsing a body; struct.error at a cut record head. A body's end may pass the data's (a cut body)."""
    size, at = len(data), 0
    while at < size:
        opcode, length = _RECORD_HEAD.unpack_from(data, at)
        start = at + _RECORD_HEAD.size
        at = start + length
        yield opcode, start, at


def _catalog_record(opcode: int, body: bytes) -> Schema | Channel:
    """A Schema or Channel record parsed from its body (opcode in _CATALOG_RECORDS)."""
    return (Schema if opcode == Opcode.SCHEMA else Channel).read(ReadDataStream(BytesIO(body)))


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
        try:
            for opcode, start, stop in _raw_records(section):
                if opcode in _CATALOG_RECORDS and stop <= len(section):
                    found.append(_catalog_record(opcode, section[start:stop]))
        except struct.error:
            pass  # a cut record head ends the section: the records before it stand
        return found
    except Exception:  # noqa: BLE001 a damaged summary only means the stream's own channel records are used
        return []


def iter_topic_data(path: Path, topics: set[str],
                    info: RecordingContents | None = None) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time, data) of the messages of `topics`, in file order: iter_messages for bulk reads.

    The mcap reader builds a record object for every message of the file, the hundreds of thousands of
    an hour's JSON copies too; this walks each chunk's data with one struct call per record and builds
    nothing for messages of other topics. The same tolerance of truncated and damaged files, the same `info`.
    """
    info = info if info is not None else RecordingContents()
    catalog = _Catalog(path, info, topics)
    known, wanted = catalog.add, catalog.wanted
    damaged = [0]
    for record in _filling(info, path, damaged, chunk_data=True):
        if isinstance(record, _ChunkData):
            try:
                for opcode, start, end in _raw_records(record):
                    if opcode == Opcode.MESSAGE:
                        channel_id, _, log_time, _ = _MESSAGE_FIXED.unpack_from(record, start)
                        topic = wanted.get(channel_id)
                        if topic is not None:
                            yield topic, log_time, record[start + _MESSAGE_FIXED.size : end]
                    elif opcode in _CATALOG_RECORDS:
                        known(_catalog_record(opcode, record[start:end]))
            except (struct.error, McapError, ValueError, EOFError, KeyError, IndexError):
                damaged[0] += 1  # a chunk that passed its CRC yet does not parse: its messages so far stand
        elif isinstance(record, Message):
            topic = wanted.get(record.channel_id)
            if topic is not None:
                yield topic, record.log_time, bytes(record.data)
        else:
            known(record)


def read_header(path: Path) -> dict[str, list[dict[str, str]]]:
    """The metadata a file begins with, read up to its first message: the recorder writes the session header
    (agent_hello, host, session, parameters) before anything else. RecordingError if the file is missing or
    not an MCAP recording."""
    info = RecordingContents()
    for record in _filling(info, path, [0]):
        if isinstance(record, Message):
            break
    return info.metadata


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
