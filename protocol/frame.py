"""The frame of wire-frame.md: inner = ver | flags | seq u16 LE | msg_id | payload | crc u16 BE."""

from __future__ import annotations

import struct
from binascii import crc_hqx
from dataclasses import dataclass

from protocol.cobs import cobs_encode
from protocol.crc import CRC_INIT, crc16_ccitt_false
from protocol.enums import INCOMPATIBLE_FLAGS_MASK, PROTOCOL_VERSION
from protocol.errors import FrameError
from protocol.registry import MAX_PAYLOAD

HEADER = struct.Struct("<BBHB")
CRC = struct.Struct(">H")
MIN_INNER = HEADER.size + CRC.size  # 7: an empty payload
MAX_INNER = HEADER.size + MAX_PAYLOAD + CRC.size  # 254
MAX_CHUNK = 256  # longest COBS chunk a receiver keeps (254 inner bytes + 2 bytes of COBS overhead)
DELIMITER = b"\x00"


@dataclass(frozen=True, slots=True)
class RawFrame:
    """A frame that passed COBS and CRC checks; the payload is not yet decoded."""

    flags: int
    seq: int
    msg_id: int
    payload: bytes
    version: int = PROTOCOL_VERSION


def build_inner(flags: int, seq: int, msg_id: int, payload: bytes) -> bytes:
    """The inner frame with its CRC; raises FrameError on an oversize payload."""
    if len(payload) > MAX_PAYLOAD:
        raise FrameError(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD}")
    body = HEADER.pack(PROTOCOL_VERSION, flags, seq & 0xFFFF, msg_id) + payload
    return body + crc_hqx(body, CRC_INIT).to_bytes(2, "big")


def encode_wire(inner: bytes) -> bytes:
    """COBS-encode an inner frame and append the 0x00 delimiter."""
    return cobs_encode(inner) + DELIMITER


def parse_inner(inner: bytes) -> RawFrame:
    """Check length, CRC and version/flags of an inner frame (already COBS-decoded)."""
    if len(inner) < MIN_INNER:
        raise FrameError(f"runt frame of {len(inner)} bytes")
    if crc16_ccitt_false(inner[:-2]) != CRC.unpack_from(inner, len(inner) - 2)[0]:
        raise FrameError("CRC mismatch")
    version, flags, seq, msg_id = HEADER.unpack_from(inner)
    if version != PROTOCOL_VERSION or flags & INCOMPATIBLE_FLAGS_MASK:
        raise FrameError(f"incompatible frame (version {version}, flags 0x{flags:02X})")
    return RawFrame(flags, seq, msg_id, inner[HEADER.size : -2], version)
