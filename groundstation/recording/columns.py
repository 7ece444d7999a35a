"""Numpy arrays of many recorded frames of one message, for replay: one structured array, a column per field."""

from __future__ import annotations

from collections.abc import Iterable

import numpy as np
from numpy.typing import NDArray

from protocol.columns import payload_records
from protocol.registry import MessageDef

# struct code of a fixed field -> numpy dtype (all little-endian, as on the wire)
_DTYPES = {"B": "<u1", "H": "<u2", "I": "<u4", "Q": "<u8", "b": "<i1", "h": "<i2", "i": "<i4", "q": "<i8",
           "f": "<f4", "d": "<f8"}


def record_dtype(definition: MessageDef) -> np.dtype[np.void]:
    """The packed (unaligned) dtype of a payload's fixed part; char[N] fields become raw bytes `S{N}`."""
    fields: list[tuple[str, str]] = []
    for f in definition.fields:
        if f.wire.is_tail:
            continue
        code = f.wire.struct_code
        fields.append((f.name, _DTYPES.get(code, f"S{f.wire.size}")))
    return np.dtype(fields)


def message_array(inner_frames: Iterable[bytes], definition: MessageDef) -> NDArray[np.void]:
    """All valid frames of `definition` among `inner_frames` as a structured array (a view, no per-row work)."""
    return np.frombuffer(payload_records(inner_frames, definition), dtype=record_dtype(definition))
