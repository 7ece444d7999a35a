"""A recording's JSON bodies: a frame's fields with its envelope (float32 fields at their wire precision), an
event's or a dump's body. The recorder writes them; the Foxglove server publishes the same."""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

import numpy as np
import orjson

from protocol import Message
from protocol.fields import F32_WIRE
from protocol.registry import message_classes

# One encoder each: json.dumps with any option builds a new JSONEncoder per call, more than a SAMPLE's encoding costs.
compact_json = json.JSONEncoder(separators=(",", ":")).encode
_compact_json_any = json.JSONEncoder(separators=(",", ":"), default=str).encode


def body_json(body: Any) -> bytes:
    """An event's or a dump's body as the recording writes it: compact JSON, anything else as its text."""
    return _compact_json_any(body).encode()


def message_json(message: Message, seq: int, flags: int, backfilled: bool) -> bytes:
    """The JSON body of a frame: its fields and the envelope, compact.

    orjson, not json: every frame is encoded, and orjson takes a fraction of the time. It writes the
    shortest text that reads back as the same float (as json does, in places with another exponent
    form) and writes NaN and infinities as null (JSON has none), as this recording always did. A message
    of numbers and text is serialised by orjson straight from its dataclass fields, and the envelope
    appended to the object; bytes fields (hex in JSON) and empty messages go through to_dict.

    A float32 field (the wire's F32) is written at its wire precision, the shortest text that is the same
    float32 (8.6, not the widened 8.600000381469727), as Parquet and the text output have it: orjson writes a
    numpy float32 so, in C. A reader widening it again gets back the float32 the agent sent.
    """
    cls = message.__class__
    envelope = b',"_seq":%d,"_flags":%d,"_backfilled":%s}' % (seq, flags, b"true" if backfilled else b"false")
    body = _F32_BODIES.get(cls)
    if body is not None:
        return orjson.dumps(body(message), option=orjson.OPT_SERIALIZE_NUMPY)[:-1] + envelope
    if cls in _DIRECT:
        return orjson.dumps(message)[:-1] + envelope
    return orjson.dumps(message.to_dict())[:-1] + envelope if cls._names else b"{" + envelope[1:]


def _float32_body(cls: type[Message]) -> Callable[[Message], dict[str, Any]] | None:
    """For a message with F32 fields: a function making its to_dict() with those fields as numpy float32 (None for
    one without). Generated from the message table, as protocol/registry.py's builder is: a dict display is about
    half the cost of filling a dict in a loop, on every SAMPLE recorded."""
    fields = cls.DEFINITION.fields
    if not any(f.wire == F32_WIRE for f in fields):
        return None
    values = [f"float32(msg.{f.name})" if f.wire == F32_WIRE else f"msg.{f.name}.hex()"
              if f.name in cls._bytes_names else f"msg.{f.name}" for f in fields]
    source = "def body(msg):\n    return {" + ", ".join(f"{f.name!r}: {v}" for f, v in zip(fields, values,
                                                                                            strict=True)) + "}\n"
    namespace: dict[str, Any] = {"float32": np.float32}
    exec(source, namespace)  # field names from our own message table
    made: Callable[[Message], dict[str, Any]] = namespace["body"]
    return made


# Messages orjson can serialise from their fields as the recording wants them (not empty, no bytes to hex).
_DIRECT = frozenset(cls for cls in message_classes().values() if cls._names and not cls._bytes_names)
_F32_BODIES = {cls: body for cls in message_classes().values() if (body := _float32_body(cls)) is not None}
