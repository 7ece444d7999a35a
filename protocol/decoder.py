"""Streaming frame decoder: bytes in, decoded frames out; never raises, memory bounded, rejects counted."""

from __future__ import annotations

from binascii import crc_hqx
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, fields
from typing import Any, NamedTuple

from protocol.chunk_verdicts import REJECTED_AS
from protocol.cobs import cobs_decode
from protocol.compiled import fast_frames
from protocol.crc import CRC_INIT
from protocol.enums import INCOMPATIBLE_FLAGS_MASK, PROTOCOL_VERSION, FrameFlag
from protocol.errors import CobsError
from protocol.frame import HEADER, MAX_CHUNK, MIN_INNER, payload_end
from protocol.registry import Message, message_classes

COMMAND_IDS_FROM = 0x80  # ids 0x80-0xFF are commands (SPEC.md section 5)
_HELLO_ID = 0x01

HEADER_SIZE = HEADER.size
unpack_header = HEADER.unpack_from
_SIGNED = int(FrameFlag.SIGNED)
REORDER_WINDOW = 64  # skipped seqs remembered: a late one among them was reordered, not lost
_SEQ_HALF = 0x8000  # a seq this far or more behind the expected one is late/duplicate, not a gap
_new_frame = tuple.__new__  # Frame(...) without the named tuple's Python-level __new__
COMPILED_FROM_BYTES = 256  # shorter reads take the stdlib path
_CompiledDecoder = Callable[[bytes, int, int, int, int], tuple[int, list[list[int]], bytes]]


@dataclass(slots=True)
class DecoderStats:
    """Counters of one decoder (one sender): good frames, bytes, rejects by cause, sequence gaps."""

    frames: int = 0
    bytes: int = 0
    cobs_errors: int = 0
    runts: int = 0
    crc_errors: int = 0
    incompatible: int = 0
    unknown_id: int = 0
    oversize: int = 0
    malformed: int = 0  # a known message whose payload could not be decoded
    lost: int = 0  # frames missing by sequence number
    duplicates: int = 0  # frames whose seq is at or behind one already seen (retries, reordering)

    @property
    def rejects(self) -> int:
        return (
            self.cobs_errors + self.runts + self.crc_errors + self.incompatible + self.unknown_id
            + self.oversize + self.malformed
        )

    def as_dict(self) -> dict[str, int]:
        return {f.name: getattr(self, f.name) for f in fields(self)}


@dataclass(frozen=True, slots=True)
class UndecodedCommand(Message):
    """What an agent's decoder hands over for a command it must answer but cannot decode (SPEC.md section 5):
    an unknown command id (answered UNSUPPORTED) or a SIGNED frame too short for its trailer (UNAUTHORIZED)."""

    truncated: bool  # SIGNED set but shorter than a trailer; else the id is unknown


class Frame(NamedTuple):
    """A received frame: header fields, the decoded message and the inner bytes (for raw recording).

    A named tuple (immutable like a frozen dataclass) because a decoder builds one per received frame.
    """

    flags: int
    seq: int
    msg_id: int
    message: Message
    inner: bytes

    @property
    def payload(self) -> bytes:
        """The message payload: without CRC, and without the signature trailer when signed."""
        return self.inner[HEADER.size : payload_end(self.inner)]

    @property
    def signed(self) -> bool:
        return bool(self.flags & _SIGNED)


def _compiled_decoder() -> _CompiledDecoder | None:
    """protocol.fast_frames.decode_buffer once it is loaded in the background; None before and without numba."""
    module = fast_frames()
    return None if module is None else module.decode_buffer  # type: ignore[no-any-return]


_PLAIN = {msg_id: (cls._struct.unpack_from, cls._build, MIN_INNER + cls.DEFINITION.fixed_size)
          for msg_id, cls in message_classes().items() if not (cls._text_indices or cls.DEFINITION.has_tail)}


@dataclass
class StreamDecoder:
    """Feed it whatever the link delivers; it returns the frames completed so far.

    One decoder serves one sender: sequence gaps are counted against that sender's counter. An agent's decoder
    (`agent=True`) hands over every command frame that passed the CRC and version checks, so that each gets its
    one ACK: unknown command ids and truncated signed commands come as an UndecodedCommand and count in
    `frames`, not in the rejects (SPEC.md section 4, counters).
    """

    stats: DecoderStats = field(default_factory=DecoderStats)
    _buffer: bytes = b""
    _discarding: bool = False  # inside a chunk already over MAX_CHUNK: drop bytes until the next 0x00
    _expected_seq: int | None = None
    compiled: bool = True  # COBS and CRC of a whole read in one compiled call where numba is installed
    # msg_id -> (struct unpack_from, builder, shortest inner frame) of messages of fixed fields only
    _plain: dict[int, tuple[Any, Any, int]] = field(default_factory=lambda: _PLAIN, repr=False)
    _skipped: deque[int] = field(default_factory=lambda: deque(maxlen=REORDER_WINDOW), repr=False)
    _classes: Mapping[int, type[Message]] = field(default_factory=message_classes, repr=False)
    agent: bool = False

    def feed(self, data: bytes) -> list[Frame]:
        stats = self.stats
        stats.bytes += len(data)
        if self._discarding:
            end = data.find(0)
            if end < 0:
                return []
            data = data[end + 1 :]
            self._discarding = False
        buffer = self._buffer + data if self._buffer else bytes(data)
        # A read of a frame or two (commands and their ACKs) is decoded faster without the compiled call's set-up.
        decode = _compiled_decoder() if self.compiled and len(buffer) >= COMPILED_FROM_BYTES else None
        frames: list[Frame] = []
        if decode is None:
            chunks = buffer.split(b"\x00")
            rest = chunks.pop()
            for chunk in chunks:
                if chunk:
                    frame = self._decode_chunk(chunk)
                    if frame is not None:
                        frames.append(frame)
        else:
            rest_at, table, inner = decode(buffer, MAX_CHUNK, MIN_INNER, PROTOCOL_VERSION, INCOMPATIBLE_FLAGS_MASK)
            rest = buffer[rest_at:]
            frames = self._frames(table, inner)
        if len(rest) > MAX_CHUNK:
            stats.oversize += 1
            self._discarding = True
            rest = b""
        self._buffer = rest
        return frames

    @property
    def buffered_bytes(self) -> int:
        """Bytes held for an unfinished chunk; never more than MAX_CHUNK."""
        return len(self._buffer)

    def reset_sequence(self) -> None:
        """Forget the expected seq (the sender rebooted or the link was re-established)."""
        self._expected_seq = None
        self._skipped.clear()

    def _decode_chunk(self, chunk: bytes) -> Frame | None:
        stats = self.stats
        if len(chunk) > MAX_CHUNK:
            stats.oversize += 1
            return None
        try:
            inner = cobs_decode(chunk)
        except CobsError:
            stats.cobs_errors += 1
            return None
        if len(inner) < MIN_INNER:
            stats.runts += 1
            return None
        if crc_hqx(inner, CRC_INIT):  # over the frame and its big-endian CRC, a good frame's CRC is 0
            stats.crc_errors += 1
            return None
        return self._decode_inner(inner)

    def _frames(self, table: list[list[int]], inner: bytes) -> list[Frame]:
        """The frames of chunks the compiled decoder checked.

        The common frame (in sequence, unsigned, a message of fixed fields only, e.g. SAMPLE) is built
        here, inline: one call per read instead of one per frame. Every other one takes _decode_inner.
        """
        plain = self._plain
        frames: list[Frame] = []
        append = frames.append
        expected = self._expected_seq
        inline = 0
        for start, length, verdict, flags, seq, msg_id in table:
            if verdict:
                self._reject(verdict)
                continue
            frame = inner[start : start + length]
            decoder = plain.get(msg_id)
            if seq == expected and decoder is not None and not flags & _SIGNED and length >= decoder[2]:
                expected = (seq + 1) & 0xFFFF
                append(_new_frame(Frame, (flags, seq, msg_id, decoder[1](decoder[0](frame, HEADER_SIZE)), frame)))
                inline += 1
                continue
            self._expected_seq = expected
            decoded = self._decode_inner(frame)
            expected = self._expected_seq
            if decoded is not None:
                append(decoded)
        self._expected_seq = expected
        self.stats.frames += inline
        return frames

    def _reject(self, verdict: int) -> None:
        """Count a chunk the compiled decoder refused."""
        name = REJECTED_AS[verdict]
        setattr(self.stats, name, getattr(self.stats, name) + 1)

    def _decode_inner(self, inner: bytes) -> Frame | None:
        """The rest of the checks and the message, for an inner frame whose COBS, length and CRC are good."""
        stats = self.stats
        version, flags, seq, msg_id = unpack_header(inner)
        if version != PROTOCOL_VERSION or flags & INCOMPATIBLE_FLAGS_MASK:
            stats.incompatible += 1
            return None
        if msg_id == _HELLO_ID:  # SPEC.md s. 1: any HELLO resets sequence tracking before it is counted
            self._expected_seq = None
        if seq == self._expected_seq:  # in order: nothing lost
            self._expected_seq = (seq + 1) & 0xFFFF
        else:
            self._track_sequence(seq)
        cls = self._classes.get(msg_id)
        if cls is None:
            if self.agent and msg_id >= COMMAND_IDS_FROM:
                return self._undecoded(flags, seq, msg_id, inner)
            stats.unknown_id += 1
            return None
        end = len(inner) - 2
        if flags & _SIGNED:  # the signature trailer is cut off before the payload is decoded (SPEC.md section 12)
            end = payload_end(inner)
            if end < 0:
                if self.agent and msg_id >= COMMAND_IDS_FROM:
                    return self._undecoded(flags, seq, msg_id, inner)
                stats.malformed += 1
                return None
        try:
            decoded = cls.unpack_from(inner, HEADER_SIZE, end)
        except Exception:  # a decoder must not raise on wire input, whatever a payload holds
            stats.malformed += 1
            return None
        stats.frames += 1
        return _new_frame(Frame, (flags, seq, msg_id, decoded, inner))

    def _undecoded(self, flags: int, seq: int, msg_id: int, inner: bytes) -> Frame:
        self.stats.frames += 1
        truncated = bool(flags & _SIGNED) and payload_end(inner) < 0
        return _new_frame(Frame, (flags, seq, msg_id, UndecodedCommand(truncated), inner))

    def _track_sequence(self, seq: int) -> None:
        expected = self._expected_seq
        if expected is not None:
            gap = (seq - expected) & 0xFFFF
            if gap >= _SEQ_HALF:
                if seq in self._skipped:  # a frame counted lost arrived late (reordered): it was not lost
                    self._skipped.remove(seq)
                    self.stats.lost -= 1
                else:
                    self.stats.duplicates += 1
                return
            self.stats.lost += gap
            self._skipped.extend((expected + i) & 0xFFFF for i in range(max(0, gap - REORDER_WINDOW), gap))
        self._expected_seq = (seq + 1) & 0xFFFF
