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
    # Common case, no full (0xFF) block: each code byte stands exactly where its zero goes, so overwrite
    # the codes in place and drop the first one; one step per zero instead of copying block by block.
    out = bytearray(encoded)
    size = len(out)
    position = 0
    while position < size:
        code = out[position]
        if code == 0xFF:
            return _decode_blocks(encoded)
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
