"""Hypothesis strategies for messages, built from each field's wire type (ranges, text and tail sizes)."""

from __future__ import annotations

from typing import Any

from hypothesis import strategies as st

from protocol import definitions, message_class
from protocol.fields import WireType
from protocol.registry import MAX_PAYLOAD, Message, MessageDef

# No NUL (a char[N] ends at the first one) and no surrogates (not encodable as UTF-8).
_CHARS = st.characters(blacklist_categories=("Cs",), blacklist_characters="\x00")


def _utf8_prefix(text: str, size: int) -> str:
    """The longest prefix of `text` whose UTF-8 fits in `size` bytes (never cut inside a character)."""
    return text.encode("utf-8")[:size].decode("utf-8", "ignore")


def field_values(wire: WireType, room: int) -> st.SearchStrategy[Any]:
    """Values of one field; `room` is what a variable-length tail may take of the payload."""
    if wire.is_tail:
        if wire.is_text:
            return st.text(_CHARS, max_size=room).map(lambda t: _utf8_prefix(t, room))
        return st.binary(max_size=room)
    if wire.spec_name.startswith("char["):
        return st.text(_CHARS, max_size=wire.size).map(lambda t: _utf8_prefix(t, wire.size))
    if wire.spec_name == "f32":
        return st.floats(width=32, allow_nan=False)
    if wire.spec_name == "f64":
        return st.floats(allow_nan=False)
    assert wire.minimum is not None and wire.maximum is not None
    return st.integers(int(wire.minimum), int(wire.maximum))


def messages_of(definition: MessageDef) -> st.SearchStrategy[Message]:
    room = MAX_PAYLOAD - definition.fixed_size
    cls = message_class(definition.msg_id)
    return st.builds(cls, **{f.name: field_values(f.wire, room) for f in definition.fields})


any_message: st.SearchStrategy[Message] = st.one_of([messages_of(d) for d in definitions()])
