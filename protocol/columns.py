"""Columnar decode of many frames of one message (replay): fixed-size records, then one column per field."""

from __future__ import annotations

import binascii
import struct
from collections.abc import Iterable
from typing import Any

from protocol.crc import CRC_INIT
from protocol.enums import INCOMPATIBLE_FLAGS_MASK, PROTOCOL_VERSION, FrameFlag
from protocol.frame import payload_end
from protocol.registry import MessageDef

_HEADER_SIZE = 5
_SIGNED = int(FrameFlag.SIGNED)


def record_struct(definition: MessageDef) -> struct.Struct:
    """The fixed part of a payload as one little-endian struct (a variable-length tail is left out)."""
    return struct.Struct("<" + "".join(f.wire.struct_code for f in definition.fields if not f.wire.is_tail))


def payload_records(inner_frames: Iterable[bytes], definition: MessageDef) -> bytes:
    """The fixed-size payloads of the valid frames of one message, concatenated.

    `inner_frames` are COBS-decoded frames with their CRC (as recorded on /raw/rx). Frames of other
    messages, with a bad CRC, or incompatible are skipped; each payload is zero-extended or cut to
    the known size (the append-only rule), so the result is a whole number of records.
    """
    size = definition.fixed_size
    msg_id = definition.msg_id
    end = _HEADER_SIZE + size
    crc_hqx = binascii.crc_hqx
    pieces: list[bytes] = []
    append = pieces.append
    for inner in inner_frames:
        length = len(inner)
        if length < 7 or inner[4] != msg_id or inner[0] != PROTOCOL_VERSION or inner[1] & INCOMPATIBLE_FLAGS_MASK:
            continue
        if crc_hqx(inner[:-2], CRC_INIT) != (inner[-2] << 8 | inner[-1]):
            continue
        if length == end + 2 and not inner[1] & _SIGNED:  # the common case: exactly the payload this build knows
            append(inner[_HEADER_SIZE:end])
        else:
            data_end = payload_end(inner)
            if data_end < 0:
                continue
            payload = inner[_HEADER_SIZE : min(end, data_end)]
            append(payload + bytes(size - len(payload)))
    return b"".join(pieces)


def columns(records: bytes, definition: MessageDef) -> dict[str, tuple[Any, ...]]:
    """One tuple of values per fixed field, from `payload_records` output (char fields stay raw bytes)."""
    layout = record_struct(definition)
    names = [f.name for f in definition.fields if not f.wire.is_tail]
    if not records:
        return {name: () for name in names}
    return dict(zip(names, zip(*layout.iter_unpack(records), strict=True), strict=True))
