"""The frame of wire-frame.md: inner = ver | flags | seq u16 LE | msg_id | payload | crc u16 BE."""

from __future__ import annotations

import struct
from binascii import crc_hqx
from collections.abc import Callable
from dataclasses import dataclass

from protocol.crc import CRC_INIT, crc16_ccitt_false
from protocol.enums import INCOMPATIBLE_FLAGS_MASK, PROTOCOL_VERSION, FrameFlag
from protocol.errors import FrameError
from protocol.registry import MAX_PAYLOAD

HEADER = struct.Struct("<BBHB")
CRC = struct.Struct(">H")
MIN_INNER = HEADER.size + CRC.size  # 7: an empty payload
MAX_INNER = HEADER.size + MAX_PAYLOAD + CRC.size  # 254
MAX_CHUNK = 255  # longest COBS chunk (delimiter excluded) a receiver keeps: a 254-byte inner frame encodes to 255
DELIMITER = b"\x00"
TRAILER_SIZE = 13  # signature trailer when SIGNED is set: link_id u8 | timestamp u48 LE | signature 6 bytes
_SIGNED = int(FrameFlag.SIGNED)
_pack_header = HEADER.pack


@dataclass(frozen=True, slots=True)
class RawFrame:
    """A frame that passed COBS and CRC checks; the payload is not yet decoded."""

    flags: int
    seq: int
    msg_id: int
    payload: bytes
    version: int = PROTOCOL_VERSION


def build_inner(flags: int, seq: int, msg_id: int, payload: bytes,
                trailer: Callable[[bytes], bytes] | None = None) -> bytes:
    """The inner frame with its CRC; raises FrameError on an oversize payload.

    With `trailer` (a Signer's), SIGNED is set and trailer(header + payload) is appended before the CRC.
    """
    room = MAX_PAYLOAD if trailer is None else MAX_PAYLOAD - TRAILER_SIZE
    if len(payload) > room:
        raise FrameError(f"payload of {len(payload)} bytes exceeds {room}")
    if trailer is None:  # every frame but signed commands: the short path
        body = _pack_header(PROTOCOL_VERSION, flags, seq & 0xFFFF, msg_id) + payload
    else:
        body = _pack_header(PROTOCOL_VERSION, flags | _SIGNED, seq & 0xFFFF, msg_id) + payload
        body += trailer(body)
    return body + crc_hqx(body, CRC_INIT).to_bytes(2, "big")


def payload_end(inner: bytes) -> int:
    """Where the message payload ends in an inner frame: before the CRC, and before the trailer when signed.

    The trailer is cut off BEFORE the payload is decoded, so it works for messages ending in bytes[] / text[] too.
    Returns -1 for a signed frame too short to hold a trailer.
    """
    if inner[1] & _SIGNED:
        return len(inner) - 2 - TRAILER_SIZE if len(inner) >= MIN_INNER + TRAILER_SIZE else -1
    return len(inner) - 2


def parse_inner(inner: bytes) -> RawFrame:
    """Check length, CRC and version/flags of an inner frame (already COBS-decoded)."""
    if len(inner) < MIN_INNER:
        raise FrameError(f"runt frame of {len(inner)} bytes")
    if crc16_ccitt_false(inner[:-2]) != CRC.unpack_from(inner, len(inner) - 2)[0]:
        raise FrameError("CRC mismatch")
    version, flags, seq, msg_id = HEADER.unpack_from(inner)
    if version != PROTOCOL_VERSION or flags & INCOMPATIBLE_FLAGS_MASK:
        raise FrameError(f"incompatible frame (version {version}, flags 0x{flags:02X})")
    end = payload_end(inner)
    if end < 0:
        raise FrameError(f"signed frame of {len(inner)} bytes has no room for its {TRAILER_SIZE}-byte trailer")
    return RawFrame(flags, seq, msg_id, inner[HEADER.size : end], version)
