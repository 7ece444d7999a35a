"""Frame encoder: message in, wire bytes out, with the sender's own sequence counter."""

from __future__ import annotations

from typing import NamedTuple

from protocol.cobs import cobs_encode
from protocol.enums import FrameFlag
from protocol.frame import DELIMITER, build_inner
from protocol.registry import Message


class EncodedFrame(NamedTuple):
    seq: int  # the frame's sequence number (an ACK echoes it)
    wire: bytes  # COBS(inner) + 0x00, ready to write


class FrameEncoder:
    """Keeps the per-sender sequence counter (+1 per frame, wraps at 65536)."""

    def __init__(self, first_seq: int = 0) -> None:
        self._seq = first_seq & 0xFFFF

    @property
    def next_seq(self) -> int:
        return self._seq

    def encode(self, message: Message, flags: int = 0) -> EncodedFrame:
        """Encode a message; commands get the ACK-requested flag set."""
        if message.DEFINITION.needs_ack:
            flags |= FrameFlag.ACK_REQUESTED
        return self.encode_payload(message.MSG_ID, message.pack(), flags)

    def encode_payload(self, msg_id: int, payload: bytes, flags: int = 0) -> EncodedFrame:
        """Frame an already packed payload (raises FrameError if it exceeds 247 bytes)."""
        inner = build_inner(flags, self._seq, msg_id, payload)
        seq = self._seq
        self._seq = (seq + 1) & 0xFFFF
        return EncodedFrame(seq, cobs_encode(inner) + DELIMITER)
