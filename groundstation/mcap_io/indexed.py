"""Reading a finished recording through its summary: chunk index, message indexes, statistics, metadata index.

A summary (`dive log info`) needs every message counted and a few topics decoded, not every message built as an
object: the summary section says where each chunk lies and each chunk's message index says where each channel's
messages lie in it, so the caller gets the decompressed chunk and an array of (log time, offset) per channel and
decodes only the channels it needs (numpy over the offsets for the many, one by one for the few). A file without
a footer, a summary, a chunk index or message indexes for all its messages (cut short, still being written, or
written by another tool) is not read here: `open_indexed` says None and the caller takes the stream reader.
"""

from __future__ import annotations

import io
import os
import struct
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from mcap.data_stream import ReadDataStream
from mcap.records import Channel, ChunkIndex, Metadata, MetadataIndex, Schema, Statistics
from numpy.typing import NDArray

from groundstation.errors import RecordingError
from groundstation.mcap_io.reader import decode_budget, decompress_chunk
from groundstation.mcap_io.writer import MAGIC

_FOOTER = struct.Struct("<BQQQI")  # opcode, length, summary start, summary offset start, summary crc
_HEAD = struct.Struct("<BQ")  # a record's opcode and length
_CHUNK_FIXED = struct.Struct("<QQQI")  # message start time, end time, uncompressed size, uncompressed crc
_OP_SCHEMA, _OP_CHANNEL, _OP_CHUNK, _OP_MESSAGE_INDEX, _OP_CHUNK_INDEX = 0x03, 0x04, 0x06, 0x07, 0x08
_OP_STATISTICS, _OP_METADATA, _OP_METADATA_INDEX = 0x0B, 0x0C, 0x0D
MESSAGE_DATA_AT = 1 + 8 + 2 + 4 + 8 + 8  # a message record's data, from its opcode: length, channel, seq, 2 times
MESSAGE_LOG_TIME_AT = 1 + 8 + 2 + 4


@dataclass(frozen=True, slots=True)
class ChannelInfo:
    topic: str
    encoding: str
    schema_name: str


@dataclass
class IndexedFile:
    """What a finished recording's summary says: channels, metadata, where the chunks are, how many messages."""

    path: Path
    size: int
    channels: dict[int, ChannelInfo]
    metadata: dict[str, list[dict[str, str]]]
    chunks: list[ChunkIndex]
    message_count: int
    compressed_bytes: int = 0  # the chunks' bytes on disk (what a progress bar counts)
    indexed_messages: int = field(default=0)  # messages the chunks' message indexes name (filled as they are read)


@dataclass(frozen=True, slots=True)
class IndexedChunk:
    """One chunk's decompressed records and, per channel id, its messages' (log time ns, offset) rows in it."""

    data: bytes
    index: dict[int, NDArray[np.uint64]]
    compressed_size: int


def open_indexed(path: Path) -> IndexedFile | None:
    """The summary of a finished recording, or None if it has none this reader can use (see the module)."""
    try:
        with open(path, "rb") as f:
            size = os.fstat(f.fileno()).st_size
            if size < 2 * len(MAGIC) + _FOOTER.size:
                return None
            f.seek(size - len(MAGIC) - _FOOTER.size)
            footer = f.read(_FOOTER.size + len(MAGIC))
            opcode, _, summary_start, _, _ = _FOOTER.unpack_from(footer)
            if opcode != 0x02 or footer[_FOOTER.size:] != MAGIC:
                return None
            end = size - len(MAGIC) - _FOOTER.size
            if not len(MAGIC) < summary_start < end:
                return None
            f.seek(summary_start)
            section = f.read(end - summary_start)
            return _summary(path, f, size, section)
    except OSError as e:
        raise RecordingError(f"cannot read {path}: {e.strerror or e}") from e
    except Exception:  # noqa: BLE001 a damaged summary only means the stream reader reads the file
        return None


def _summary(path: Path, f: io.BufferedReader, size: int, section: bytes) -> IndexedFile | None:
    schemas: dict[int, str] = {}
    channels: dict[int, ChannelInfo] = {}
    chunks: list[ChunkIndex] = []
    metadata_at: list[MetadataIndex] = []
    statistics: Statistics | None = None
    at = 0
    while at + _HEAD.size <= len(section):
        opcode, length = _HEAD.unpack_from(section, at)
        body = section[at + _HEAD.size: at + _HEAD.size + length]
        at += _HEAD.size + length
        if len(body) != length:
            return None
        stream = ReadDataStream(io.BytesIO(body))
        if opcode == _OP_SCHEMA:
            schema = Schema.read(stream)
            schemas[schema.id] = schema.name
        elif opcode == _OP_CHANNEL:
            channel = Channel.read(stream)
            channels[channel.id] = ChannelInfo(channel.topic, channel.message_encoding,
                                               schemas.get(channel.schema_id, ""))
        elif opcode == _OP_CHUNK_INDEX:
            chunks.append(ChunkIndex.read(stream))
        elif opcode == _OP_METADATA_INDEX:
            metadata_at.append(MetadataIndex.read(stream))
        elif opcode == _OP_STATISTICS:
            statistics = Statistics.read(stream)
    if statistics is None or (statistics.message_count and not chunks) \
            or len(metadata_at) != statistics.metadata_count:
        return None
    for chunk in chunks:
        if chunk.chunk_start_offset + chunk.chunk_length + chunk.message_index_length > size:
            return None
    metadata: dict[str, list[dict[str, str]]] = {}
    for entry in sorted(metadata_at, key=lambda e: e.offset):
        if entry.offset + entry.length > size or entry.length < _HEAD.size:
            return None
        f.seek(entry.offset)
        record = f.read(entry.length)
        if record[0] != _OP_METADATA:
            return None
        read = Metadata.read(ReadDataStream(io.BytesIO(record[_HEAD.size:])))
        metadata.setdefault(read.name, []).append(dict(read.metadata))
    chunks.sort(key=lambda c: c.chunk_start_offset)
    return IndexedFile(path, size, channels, metadata, chunks, statistics.message_count,
                       sum(c.chunk_length for c in chunks))


def iter_indexed_chunks(indexed: IndexedFile, damaged: list[int]) -> Iterator[IndexedChunk]:
    """Each chunk decompressed (within the file's budget, as the stream reader does) with its message indexes.

    A damaged chunk (CRC, decompression, a message index pointing outside it) is skipped and counted in
    damaged[0]. Every message index is counted in indexed.indexed_messages, a damaged chunk's too, so the caller
    can tell that the indexes named every message the statistics count (else a message lies outside them).
    """
    budget = decode_budget(indexed.size)
    with open(indexed.path, "rb") as f:
        for chunk in indexed.chunks:
            f.seek(chunk.chunk_start_offset)
            record = f.read(chunk.chunk_length + chunk.message_index_length)
            index = _message_indexes(record, chunk.chunk_length)
            indexed.indexed_messages += sum(len(rows) for rows in index.values())
            data = _chunk_data(record, chunk, budget, indexed.path)
            if data is None or any(len(rows) and int(rows[:, 1].max()) + MESSAGE_DATA_AT > len(data)
                                   for rows in index.values()):
                damaged[0] += 1
                continue
            yield IndexedChunk(data, index, chunk.chunk_length)


def _chunk_data(record: bytes, chunk: ChunkIndex, budget: list[int], path: Path) -> bytes | None:
    try:
        opcode, length = _HEAD.unpack_from(record)
        if opcode != _OP_CHUNK or _HEAD.size + length != chunk.chunk_length:
            return None
        at = _HEAD.size
        _, _, uncompressed_size, crc = _CHUNK_FIXED.unpack_from(record, at)
        at += _CHUNK_FIXED.size
        (name_length,) = struct.unpack_from("<I", record, at)
        compression = record[at + 4: at + 4 + name_length].decode()
        at += 4 + name_length
        (data_length,) = struct.unpack_from("<Q", record, at)
        at += 8
        if at + data_length > chunk.chunk_length:
            return None
        return decompress_chunk(compression, record[at: at + data_length], uncompressed_size, crc, budget, path)
    except (struct.error, UnicodeDecodeError, ValueError, EOFError):
        return None
    except RecordingError:
        raise
    except Exception:  # noqa: BLE001 zstandard raises its own errors for damaged data
        return None


def _message_indexes(record: bytes, start: int) -> dict[int, NDArray[np.uint64]]:
    """The message index records after a chunk: channel id -> (n, 2) array of (log time, offset)."""
    index: dict[int, NDArray[np.uint64]] = {}
    at = start
    while at + _HEAD.size + 6 <= len(record):
        opcode, length = _HEAD.unpack_from(record, at)
        end = at + _HEAD.size + length
        if opcode != _OP_MESSAGE_INDEX or end > len(record):
            break
        channel_id, byte_length = struct.unpack_from("<HI", record, at + _HEAD.size)
        count = min(byte_length, length - 6) // 16
        rows = np.frombuffer(record, dtype="<u8", count=2 * count, offset=at + _HEAD.size + 6).reshape(count, 2)
        index[channel_id] = rows if channel_id not in index else np.concatenate([index[channel_id], rows])
        at = end
    return index
