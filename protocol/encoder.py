"""Frame encoder: message in, wire bytes out, with the sender's own sequence counter (and optional signer)."""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, NamedTuple

from protocol.cobs import CobsFrameEncoder, cobs_decode
from protocol.compiled import fast_frames
from protocol.enums import PROTOCOL_VERSION, FrameFlag
from protocol.frame import HEADER, build_inner, payload_end
from protocol.registry import Message

if TYPE_CHECKING:
    from protocol.signing import Signer


class EncodedFrame(NamedTuple):
    seq: int  # the frame's sequence number (an ACK echoes it)
    wire: bytes  # COBS(inner) + 0x00, ready to write


_ACK_REQUESTED = int(FrameFlag.ACK_REQUESTED)  # a plain int: IntFlag arithmetic is slow
_new_encoded = tuple.__new__  # EncodedFrame(...) without the named tuple's Python-level __new__


COMPILED_MAX_PAYLOAD = 246  # protocol.fast_frames.COMPILED_MAX_PAYLOAD (a test checks they agree)


class FrameEncoder:
    """Keeps the per-sender sequence counter (+1 per frame, wraps at 65536).

    With a `signer`, every frame gets flag bit 4 (SIGNED) and a signature trailer (SPEC.md section 12).
    """

    def __init__(self, first_seq: int = 0, signer: Signer | None = None, compiled: bool = True) -> None:
        self._seq = first_seq & 0xFFFF
        self.signer = signer
        self._cobs = CobsFrameEncoder()  # senders repeat a few zero patterns (SAMPLEs): cached COBS codes
        # Header, CRC and COBS of an unsigned frame in one compiled call, where numba is installed, once loaded.
        self._use_compiled = compiled
        self._compiled: Callable[[bytes, int, int, int], bytes] | None = None

    @property
    def next_seq(self) -> int:
        return self._seq

    @property
    def compiled(self) -> bool:
        """Whether the compiled writer is used once loaded (its load starts at the first frame encoded)."""
        return self._use_compiled

    @compiled.setter
    def compiled(self, use: bool) -> None:
        self._use_compiled = use
        if not use:
            self._compiled = None

    def take_seqs(self, count: int) -> int:
        """Reserve the seqs of `count` frames framed elsewhere (a compiled batch of SAMPLEs); returns the first."""
        seq = self._seq
        self._seq = (seq + count) & 0xFFFF
        return seq

    def encode(self, message: Message, flags: int = 0) -> EncodedFrame:
        """Encode a message; commands get the ACK-requested flag set."""
        if message.DEFINITION.needs_ack:
            flags |= _ACK_REQUESTED
        payload = message.pack()
        compiled = self._compiled or self._compiled_writer()
        if compiled is not None and self.signer is None and len(payload) <= COMPILED_MAX_PAYLOAD:
            # encode_payload's compiled path, inlined: a sender of SAMPLEs saves a call per frame.
            seq = self._seq
            self._seq = (seq + 1) & 0xFFFF
            return _new_encoded(EncodedFrame, (seq, compiled(payload, flags, seq, message.MSG_ID)))
        return self.encode_payload(message.MSG_ID, payload, flags)

    def encode_payload(self, msg_id: int, payload: bytes, flags: int = 0) -> EncodedFrame:
        """Frame an already packed payload (raises FrameError if it exceeds 247 bytes, 234 when signed)."""
        seq = self._seq
        compiled = self._compiled or self._compiled_writer()
        if compiled is not None and self.signer is None and len(payload) <= COMPILED_MAX_PAYLOAD:
            self._seq = (seq + 1) & 0xFFFF
            return _new_encoded(EncodedFrame, (seq, compiled(payload, flags, seq, msg_id)))
        return _new_encoded(EncodedFrame, (seq, self.wire(self.next_inner(msg_id, payload, flags))))

    def _compiled_writer(self) -> Callable[[bytes, int, int, int], bytes] | None:
        """The compiled writer once protocol.compiled has loaded it (None until then, and without numba)."""
        if self._use_compiled:
            module = fast_frames()
            if module is not None:
                self._compiled = module.frame_writer(PROTOCOL_VERSION)
        return self._compiled

    def next_inner(self, msg_id: int, payload: bytes, flags: int = 0) -> bytes:
        """The inner frame of a payload with the next seq, for senders that keep it (the agent's on-board log)."""
        seq = self._seq
        inner = build_inner(flags, seq, msg_id, payload, self._trailer())
        self._seq = (seq + 1) & 0xFFFF
        return inner

    def wire(self, inner: bytes) -> bytes:
        """COBS(inner) + 0x00, from the cached codes of its zero pattern."""
        return self._cobs.encode(inner)

    def retry(self, wire: bytes) -> bytes:
        """The wire bytes to re-send a frame: the same seq and payload; re-signed with a fresh timestamp if signed.

        Re-sending a signed frame byte for byte would be refused as a replay, so a retry carries a new trailer; the
        agent still recognises it as a retry by (msg_id, seq) and does not run the command twice.
        """
        if self.signer is None:
            return wire
        inner = cobs_decode(wire[:-1])
        end = payload_end(inner)
        flags = inner[1] & ~FrameFlag.SIGNED
        _, _, seq, msg_id = HEADER.unpack_from(inner)
        return self.wire(build_inner(flags, seq, msg_id, inner[HEADER.size : end], self._trailer()))

    def _trailer(self) -> Callable[[bytes], bytes] | None:
        return self.signer.trailer if self.signer is not None else None
