"""Compiled COBS decoding and CRC checking of every chunk in one read: the fast path beside cobs.py.

numba comes with the ground station and the virtual agent, not with the protocol package, so this
module is imported only where a decoder first needs it (`protocol.decoder` falls back to the stdlib codec
of cobs.py without numba). cobs.py stays the definition: tests check these kernels byte for byte
against it (hypothesis). Compiled on first use and cached on disk (`cache=True`).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numba
import numpy as np
from numba import njit
from numpy.typing import NDArray

from protocol.chunk_verdicts import (
    CHUNK_COBS_ERROR,
    CHUNK_CRC_ERROR,
    CHUNK_INCOMPATIBLE,
    CHUNK_OK,
    CHUNK_OVERSIZE,
    CHUNK_RUNT,
)
from protocol.crc import CRC_INIT


def _crc_table() -> NDArray[np.uint16]:
    """CRC-16/CCITT-FALSE (poly 0x1021), one entry per byte value, for the table-driven kernel."""
    table = np.zeros(256, np.uint16)
    for byte in range(256):
        crc = byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else crc << 1
        table[byte] = crc & 0xFFFF
    return table


_CRC_TABLE = _crc_table()


@njit(cache=True, nogil=True, inline="always")
def crc_step(crc: int, byte: int) -> int:
    """CRC-16/CCITT-FALSE (protocol.crc) advanced by one byte, from the table."""
    return ((crc << 8) & 0xFFFF) ^ _CRC_TABLE[((crc >> 8) ^ byte) & 0xFF]


@njit(cache=True, nogil=True)
def decode_chunks(buffer: NDArray[np.uint8], max_chunk: int, min_inner: int, version: int,
                  incompatible_flags: int) -> tuple[int, int, NDArray[np.int64], NDArray[np.uint8]]:
    """COBS-decode every 0x00-terminated chunk of `buffer`, check its CRC residue, version and flags.

    Returns (chunks, end of the last delimiter, table, inner bytes). Row i of the table describes chunk i:
    (start, length, verdict, flags, seq, msg_id); it decoded to inner[start : start + length] and its
    verdict is decoder.CHUNK_OK or the reject. Empty chunks (two delimiters in a row) are skipped, as
    StreamDecoder does; the bytes after the last delimiter are left for the next read.
    """
    size = buffer.size
    inner = np.empty(size, np.uint8)
    slots = size // 2 + 1
    table = np.zeros((slots, 6), np.int64)
    count = 0
    written = 0
    chunk_start = 0
    for index in range(size):
        if buffer[index] != 0:
            continue
        chunk_end = index
        if chunk_end == chunk_start:
            chunk_start = index + 1
            continue
        start = written
        verdict = CHUNK_OK
        if chunk_end - chunk_start > max_chunk:
            verdict = CHUNK_OVERSIZE
        else:
            position = chunk_start
            while position < chunk_end:
                code = np.int64(buffer[position])
                block_end = position + code
                if block_end > chunk_end:
                    verdict = CHUNK_COBS_ERROR
                    break
                for k in range(position + 1, block_end):
                    inner[written] = buffer[k]
                    written += 1
                if code != 0xFF and block_end < chunk_end:
                    inner[written] = 0
                    written += 1
                position = int(block_end)
            if verdict == CHUNK_OK and written - start < min_inner:
                verdict = CHUNK_RUNT
            if verdict == CHUNK_OK:
                crc = CRC_INIT
                for k in range(start, written):
                    crc = crc_step(crc, inner[k])
                if crc != 0:  # over the frame and its big-endian CRC, a good frame's CRC is 0
                    verdict = CHUNK_CRC_ERROR
            if verdict == CHUNK_OK and (inner[start] != version or inner[start + 1] & incompatible_flags):
                verdict = CHUNK_INCOMPATIBLE
            if verdict != CHUNK_OK:
                written = start
            else:
                table[count, 3] = inner[start + 1]
                table[count, 4] = inner[start + 2] | (np.int64(inner[start + 3]) << 8)
                table[count, 5] = inner[start + 4]
        table[count, 0] = start
        table[count, 1] = written - start
        table[count, 2] = verdict
        count += 1
        chunk_start = index + 1
    return count, chunk_start, table, inner[:written]


def decode_buffer(data: bytes, max_chunk: int, min_inner: int, version: int,
                  incompatible_flags: int) -> tuple[int, list[list[int]], bytes]:
    """decode_chunks on bytes, with Python lists and bytes out (what a per-frame Python loop reads fastest).

    Returns (end of the last delimiter, one [start, length, verdict, flags, seq, msg_id] per chunk, the
    inner bytes of the good chunks).
    """
    count, rest, table, inner = decode_chunks(np.frombuffer(data, np.uint8), max_chunk, min_inner, version,
                                              incompatible_flags)
    return rest, table[:count].tolist(), inner.tobytes()


@njit(cache=True, nogil=True, inline="always")
def crc_into(frame: NDArray[np.uint8], body: int) -> None:
    """The CRC of frame[:body] into frame[body:body + 2], big-endian (the inner frame's trailer)."""
    crc = CRC_INIT
    for k in range(body):
        crc = crc_step(crc, frame[k])
    frame[body] = crc >> 8
    frame[body + 1] = crc & 0xFF


@njit(cache=True, nogil=True, inline="always")
def cobs_encode_into(source: NDArray[np.uint8], length: int, out: NDArray[np.uint8], start: int) -> int:
    """COBS(source[:length]) + the 0x00 delimiter into out[start:]; returns the end. For chunks shorter than
    254 bytes, where no block can be full: each zero becomes the distance to the next one."""
    code_at = start  # where the code of the block in progress goes
    written = start + 1
    for k in range(length):
        byte = source[k]
        if byte == 0:
            out[code_at] = written - code_at
            code_at = written
        else:
            out[written] = byte
        written += 1
    out[code_at] = written - code_at
    out[written] = 0
    return written + 1


INNER_AT = 256  # encode_frame assembles the inner frame here in its output buffer, past any wire bytes


@njit(cache=True, nogil=True)
def encode_frame(payload: bytes, header: int, out: NDArray[np.uint8]) -> int:
    """The unsigned frame of `payload` as wire bytes (COBS(inner) + 0x00) into `out`; returns their count.

    `header` holds the five header bytes, little-endian (version, flags, seq low, seq high, msg_id): one
    argument instead of four, each costing its unboxing per call. For inner frames shorter than 254 bytes
    (payloads up to 246 bytes), where no COBS block can be full. `out` holds at least 2 * INNER_AT bytes:
    nothing is allocated, the inner frame is assembled and checksummed in its upper half, then COBS-encoded.
    """
    inner = out[INNER_AT:]
    body = 5 + len(payload)
    crc = CRC_INIT
    for k in range(body):  # assembled and checksummed in one pass
        byte = (header >> (8 * k)) & 0xFF if k < 5 else payload[k - 5]
        inner[k] = byte
        crc = crc_step(crc, byte)
    inner[body] = crc >> 8
    inner[body + 1] = crc & 0xFF
    return cobs_encode_into(inner, body + 2, out, 0)


COMPILED_MAX_PAYLOAD = 246  # longer payloads take the stdlib path (a full COBS block is possible there)


def frame_writer(version: int) -> Callable[[bytes, int, int, int], bytes]:
    """encode_frame with its own output buffer, as `wire(payload, flags, seq, msg_id) -> wire bytes`.

    One per FrameEncoder (the buffer is reused between calls). A closure, not a class: it runs for
    every frame sent, and local variables are the cheapest lookups. Called through the compiled entry
    point, without numba's per-call argument typing. Payloads up to COMPILED_MAX_PAYLOAD bytes.
    """
    entry = _encode_entry()
    out = np.zeros(2 * INNER_AT, np.uint8)
    view = memoryview(out)  # type: ignore[arg-type]  # numpy arrays are buffers

    def wire(payload: bytes, flags: int, seq: int, msg_id: int) -> bytes:
        return view[: entry(payload, version | flags << 8 | seq << 16 | msg_id << 32, out)].tobytes()

    return wire


_entry: Any = None


def _encode_entry() -> Any:
    """encode_frame compiled for bytes payloads (compiled once per process, loaded from the cache after)."""
    global _entry
    if _entry is None:
        out = np.zeros(1, np.uint8)
        _entry = encode_frame.compile((numba.typeof(b""), numba.int64, numba.typeof(out)))
    return _entry


def warm_up() -> None:
    """Compile (or load from the cache) every kernel here, so that no frame waits for it."""
    frame_writer(1)(b"\x00", 0, 0, 0)
    decode_buffer(b"\x02\x01\x00" * 100, 255, 7, 1, 0)
