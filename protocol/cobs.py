"""Canonical COBS (Consistent Overhead Byte Stuffing), byte-identical to the `cobs` package."""

from __future__ import annotations

from protocol.errors import CobsError

_MAX_BLOCK = 254  # data bytes a 0xFF code block carries


def cobs_encode(data: bytes) -> bytes:
    """Encode `data` so that it contains no 0x00; the caller appends the 0x00 delimiter."""
    out = bytearray()
    if len(data) < _MAX_BLOCK:  # every frame: no block can be full, so one code per zero-separated block
        for block in data.split(b"\x00"):
            out.append(len(block) + 1)
            out += block
        return bytes(out)
    blocks = data.split(b"\x00")
    last = len(blocks) - 1
    for index, block in enumerate(blocks):
        while len(block) >= _MAX_BLOCK:
            out.append(0xFF)
            out += block[:_MAX_BLOCK]
            block = block[_MAX_BLOCK:]
            # A full block carries no implied zero; an empty rest at the very end needs no code.
            if not block and index == last:
                return bytes(out)
        out.append(len(block) + 1)
        out += block
    return bytes(out)


def cobs_decode(encoded: bytes) -> bytes:
    """Decode one COBS chunk (without its 0x00 delimiter); raises CobsError if it is malformed."""
    if b"\x00" in encoded:
        raise CobsError("zero byte inside a COBS chunk")
    size = len(encoded)
    if size > _MAX_BLOCK:  # only a chunk this long can hold a full (0xFF) block
        return _decode_blocks(encoded)
    # Every frame: each code byte stands exactly where its zero goes, so overwrite the codes in place
    # and drop the first one; one step per zero instead of copying block by block. (A 0xFF code in
    # so short a chunk runs past its end, which the length check below reports.)
    out = bytearray(encoded)
    position = 0
    while position < size:
        code = out[position]
        out[position] = 0
        position += code
    if position != size:
        raise CobsError(f"COBS code runs past the end of a {size}-byte chunk")
    del out[:1]
    return bytes(out)


def _decode_blocks(encoded: bytes) -> bytes:
    """The general decoder, for chunks with a full 254-byte block."""
    out = bytearray()
    position = 0
    size = len(encoded)
    while position < size:
        code = encoded[position]
        end = position + code
        if end > size:
            raise CobsError(f"COBS code {code} runs past the end of a {size}-byte chunk")
        out += encoded[position + 1 : end]
        if code != 0xFF and end < size:
            out.append(0)
        position = end
    return bytes(out)


class CobsFrameEncoder:
    """COBS-encodes frames into wire bytes (with the 0x00 delimiter) faster for senders of similar frames.

    The code bytes of a short frame depend only on where its zero bytes are, and a stream of SAMPLEs
    repeats a few hundred zero patterns. Each pattern's code bytes are kept once (at most
    `max_patterns`, then forgotten and relearned); a known pattern is encoded by one integer OR
    instead of a Python step per zero. Byte-identical to `cobs_encode(frame) + b"\\x00"`.
    """

    def __init__(self, max_patterns: int = 4096) -> None:
        self._codes: dict[bytes, int] = {}
        self._max_patterns = max_patterns

    def encode(self, frame: bytes) -> bytes:
        """The wire bytes of one frame."""
        size = len(frame)
        if size >= _MAX_BLOCK:
            return cobs_encode(frame) + b"\x00"
        pattern = frame.translate(_ZERO_PATTERN)
        # The frame shifted by one byte, with room for the first code in front and the delimiter behind.
        body = int.from_bytes(frame, "big") << 8
        codes = self._codes.get(pattern)
        if codes is None:
            wire = cobs_encode(frame) + b"\x00"
            if len(self._codes) >= self._max_patterns:
                self._codes.clear()
            self._codes[pattern] = int.from_bytes(wire, "big") ^ body  # the code bytes, zero elsewhere
            return wire
        return (body | codes).to_bytes(size + 2, "big")


# Maps 0x00 to 0x01 and every other byte to 0x00: the zero pattern of a frame, as a dictionary key.
_ZERO_PATTERN = bytes([1] + [0] * 255)
