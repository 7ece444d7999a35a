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


class CobsChunkDecoder:
    """Decodes COBS chunks faster for receivers of similar frames: the mirror of CobsFrameEncoder.

    A short chunk's code bytes stand where its frame's zeros go, and they chain: each says where the next one
    is. The chain last seen for a chunk's length and first code is kept; if the new chunk holds the same codes at
    the same places, it follows the same chain to its end, so it decodes by zeroing those places (two integer
    operations) instead of a Python step per zero. Any other chunk takes cobs_decode and its chain is kept.
    Commands, their ACKs and parameters repeat their chains; a learning agent's SAMPLEs mostly do not (about one
    in five), so a length and first code whose chain changed several chunks in a row is no longer learned: its
    chunks take cobs_decode. Byte-identical to `cobs_decode`, errors included.
    """

    def __init__(self, max_patterns: int = 4096) -> None:
        # size << 8 | first code -> the chain (where the codes are, as a mask; their values; every other byte but
        # the first), or () for a key given up on
        self._chains: dict[int, tuple[int, ...]] = {}
        self._changes: dict[int, int] = {}  # keys whose last chunks each brought a new chain: how many in a row
        self._max_patterns = max_patterns

    def decode(self, encoded: bytes) -> bytes:
        """Decode one COBS chunk (without its 0x00 delimiter); raises CobsError if it is malformed."""
        size = len(encoded)
        if not size or size > _MAX_BLOCK:
            return cobs_decode(encoded)
        key = size << 8 | encoded[0]
        chain = self._chains.get(key)
        if chain:
            value = int.from_bytes(encoded, "big")
            if value & chain[0] == chain[1] and b"\x00" not in encoded:
                if key in self._changes:
                    del self._changes[key]
                return (value & chain[2]).to_bytes(size - 1, "big")
        elif chain is not None:  # given up on
            return cobs_decode(encoded)
        decoded = cobs_decode(encoded)  # checks it, and raises on a malformed chunk
        self._learn(key, encoded, chain is not None)
        return decoded

    def _learn(self, key: int, encoded: bytes, changed: bool) -> None:
        if len(self._chains) >= self._max_patterns:
            self._chains.clear()
            self._changes.clear()
        if changed:
            changes = self._changes.get(key, 0) + 1
            if changes >= _CHANGES_BEFORE_GIVING_UP:
                self._chains[key] = ()
                del self._changes[key]
                return
            self._changes[key] = changes
        self._chains[key] = _chain(encoded)


_CHANGES_BEFORE_GIVING_UP = 4  # a new chain this many chunks in a row: the key's chains do not repeat


def _chain(encoded: bytes) -> tuple[int, int, int]:
    """The code bytes of a valid short chunk: where they are (a mask), their values, and the mask of the rest."""
    size = len(encoded)
    codes = bytearray(size)
    position = 0
    while position < size:
        codes[position] = encoded[position]
        position += encoded[position]
    places = int.from_bytes(codes.translate(_CODE_PLACES), "big")
    rest = ~places & ((1 << 8 * (size - 1)) - 1)
    return places, int.from_bytes(codes, "big"), rest


_CODE_PLACES = bytes([0] + [0xFF] * 255)  # a code byte (never 0) to 0xFF, the zeros between codes stay 0


# Maps 0x00 to 0x01 and every other byte to 0x00: the zero pattern of a frame, as a dictionary key.
_ZERO_PATTERN = bytes([1] + [0] * 255)
