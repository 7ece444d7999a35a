"""The message definition table: one `@message` declaration per message generates pack/unpack."""

from __future__ import annotations

import dataclasses
import hashlib
import struct
import typing
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import StrEnum
from operator import attrgetter
from types import MappingProxyType
from typing import Any, ClassVar, Self

from protocol.errors import PayloadError, UnknownMessageError
from protocol.fields import WireType

MAX_PAYLOAD = 247


class Direction(StrEnum):
    AGENT_TO_GROUND = "agent → ground"
    GROUND_TO_AGENT = "ground → agent"
    BOTH = "both"


@dataclass(frozen=True)
class FieldDef:
    name: str
    wire: WireType
    offset: int
    unit: str
    doc: str


@dataclass(frozen=True)
class MessageDef:
    msg_id: int
    name: str
    direction: Direction
    needs_ack: bool
    chunked: bool
    doc: str
    fields: tuple[FieldDef, ...]
    fixed_size: int  # bytes before the optional variable-length tail
    has_tail: bool


class Message:
    """Base of every message; subclasses are frozen dataclasses declared with `@message`."""

    MSG_ID: ClassVar[int]
    DEFINITION: ClassVar[MessageDef]
    _struct: ClassVar[struct.Struct]
    _getter: ClassVar[Any]
    _text_indices: ClassVar[tuple[int, ...]]
    _build: ClassVar[Any]  # values in declaration order -> instance, without __init__ (see _builder)
    _names: ClassVar[tuple[str, ...]]  # field names in declaration order
    _bytes_names: ClassVar[tuple[str, ...]]  # fields holding bytes (hex in to_dict)

    def pack(self) -> bytes:
        """The payload bytes, little-endian, in declaration order."""
        values = self._getter(self)
        return self.pack_values(values) if len(self.DEFINITION.fields) == 1 else self.pack_values(*values)

    @classmethod
    def pack_values(cls, *values: Any) -> bytes:
        """`cls(*values).pack()` without building the message, for senders of many messages.

        Values in declaration order; byte-identical to pack(). Building a frozen dataclass costs more
        than packing it, which matters to an agent sending a SAMPLE every control step and an ACK for every
        command.
        """
        definition = cls.DEFINITION
        try:
            packed: Sequence[Any] = cls._encoded_texts(values) if cls._text_indices else values
            if not definition.has_tail:
                return cls._struct.pack(*packed)
            tail = packed[-1]
            if isinstance(tail, str):
                tail = tail.encode("utf-8")
            body: bytes = cls._struct.pack(*packed[:-1]) + tail
        except (struct.error, AttributeError, TypeError) as e:
            raise PayloadError(f"{definition.name}: {e}") from e
        if len(body) > MAX_PAYLOAD:
            raise PayloadError(f"{definition.name}: payload of {len(body)} bytes exceeds {MAX_PAYLOAD}")
        return body

    @classmethod
    def _encoded_texts(cls, values: Sequence[Any]) -> list[Any]:
        """The values with each text field as its UTF-8 bytes, cut to the field at a character boundary."""
        fields = cls.DEFINITION.fields
        encoded_values = list(values)
        for index in cls._text_indices:
            encoded = encoded_values[index].encode("utf-8")
            size = fields[index].wire.size
            if len(encoded) > size:  # SPEC.md s. 3: cut at a character boundary (struct would cut inside one)
                encoded = encoded[:size].decode("utf-8", errors="ignore").encode("utf-8")
            encoded_values[index] = encoded
        return encoded_values

    @classmethod
    def unpack(cls, payload: bytes) -> Self:
        """Decode a payload: a short one is zero-extended, extra trailing bytes are ignored."""
        definition = cls.DEFINITION
        size = definition.fixed_size
        if len(payload) < size:
            payload = payload + bytes(size - len(payload))
        values = cls._struct.unpack_from(payload)
        if cls._text_indices:
            values = _decode_texts(values, cls._text_indices)
        if definition.has_tail:
            tail = payload[size:]
            values = (*values, tail.decode("utf-8", "replace") if definition.fields[-1].wire.is_text else tail)
        built: Self = cls._build(values)
        return built

    @classmethod
    def unpack_from(cls, frame: bytes, start: int, end: int) -> Self:
        """unpack(frame[start:end]) without the copy when the payload holds every fixed field (a decoder's path)."""
        if end - start >= cls.DEFINITION.fixed_size and not (cls._text_indices or cls.DEFINITION.has_tail):
            built: Self = cls._build(cls._struct.unpack_from(frame, start))
            return built
        return cls.unpack(frame[start:end])

    def to_dict(self) -> dict[str, Any]:
        """Field values by name (tail bytes as hex), the JSON form used by recordings and vectors."""
        names = self._names
        values = self._getter(self)
        out = dict(zip(names, (values,) if len(names) == 1 else values, strict=True))
        for name in self._bytes_names:
            out[name] = out[name].hex()
        return out

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> Self:
        converted = dict(values)
        for f in cls.DEFINITION.fields:
            if f.wire.spec_name == "bytes[]" and isinstance(converted.get(f.name), str):
                converted[f.name] = bytes.fromhex(converted[f.name])
        return cls(**converted)


def _decode_texts(values: tuple[Any, ...], indices: tuple[int, ...]) -> tuple[Any, ...]:
    mutable = list(values)
    for index in indices:
        mutable[index] = mutable[index].split(b"\x00", 1)[0].decode("utf-8", "replace")
    return tuple(mutable)


_BY_ID: dict[int, type[Message]] = {}
_BY_NAME: dict[str, type[Message]] = {}


_M = typing.TypeVar("_M", bound=type[Message])


# dataclass_transform tells type checkers that a `@message` class gets a dataclass __init__ (every field
# has a default, the `wire(...)` call, so every argument is optional, as on the wire).
@typing.dataclass_transform(frozen_default=True)
def message(
    msg_id: int, name: str, direction: Direction, *, ack: bool = False, chunked: bool = False
) -> typing.Callable[[_M], _M]:
    """Declare a message: registers it in the table and generates its wire layout."""

    def declare(cls: Any) -> Any:
        if msg_id in _BY_ID or name in _BY_NAME:
            raise ValueError(f"message {name} / 0x{msg_id:02X} declared twice")
        _check_id_range(msg_id, direction, name)
        cls = dataclasses.dataclass(frozen=True, slots=True)(cls)
        hints = typing.get_type_hints(cls, include_extras=True)
        fields: list[FieldDef] = []
        offset = 0
        for f in dataclasses.fields(cls):
            wire_type = next(m for m in typing.get_args(hints[f.name])[1:] if isinstance(m, WireType))
            fields.append(FieldDef(f.name, wire_type, offset, f.metadata.get("unit", ""), f.metadata["doc"]))
            offset += wire_type.size
        has_tail = bool(fields) and fields[-1].wire.is_tail
        if any(f.wire.is_tail for f in fields[:-1]):
            raise ValueError(f"{name}: only the last field may take the rest of the payload")
        fixed = [f for f in fields if not f.wire.is_tail]
        cls.MSG_ID = msg_id
        cls.DEFINITION = MessageDef(
            msg_id, name, direction, ack, chunked, (cls.__doc__ or "").strip(), tuple(fields), offset, has_tail
        )
        cls._struct = struct.Struct("<" + "".join(f.wire.struct_code for f in fixed))
        cls._getter = attrgetter(*[f.name for f in fields]) if fields else staticmethod(lambda _self: ())
        cls._text_indices = tuple(i for i, f in enumerate(fixed) if f.wire.is_text)
        cls._build = staticmethod(_builder(cls, [f.name for f in fields]))
        cls._names = tuple(f.name for f in fields)
        cls._bytes_names = tuple(f.name for f in fields if f.wire.spec_name == "bytes[]")
        if len(fields) > 1 and not (cls._text_indices or has_tail):
            setattr(cls, "pack", _plain_packer(name, cls._struct, cls._getter))  # noqa: B010 (mypy: no method assignment)
        _BY_ID[msg_id] = cls
        _BY_NAME[name] = cls
        return cls

    return declare


def _plain_packer(name: str, layout: struct.Struct, getter: Any) -> typing.Callable[[Any], bytes]:
    """Message.pack for a message of fixed fields only (most of them, SAMPLE among them): one struct call."""
    pack = layout.pack

    def packed(self: Any) -> bytes:
        try:
            return pack(*getter(self))
        except (struct.error, TypeError) as e:
            raise PayloadError(f"{name}: {e}") from e

    packed.__doc__ = Message.pack.__doc__
    return packed


def _builder(cls: type, names: list[str]) -> typing.Callable[[tuple[Any, ...]], Any]:
    """A function that makes an instance of the frozen slots dataclass `cls` from its field values.

    The dataclass __init__ sets each field through object.__setattr__ (a global lookup and a call per
    field); a decoder building every received message pays that per frame. Calling the slot
    descriptors' setters directly gives the same object at about half the cost. Only for values that
    come from the struct, which already has the field types.
    """
    setters = {f"set_{i}": getattr(cls, name).__set__ for i, name in enumerate(names)}
    lines = ["def build(values):", "    obj = new(cls)"]
    lines += [f"    set_{i}(obj, values[{i}])" for i in range(len(names))]
    source = "\n".join([*lines, "    return obj", ""])
    namespace: dict[str, Any] = {"new": object.__new__, "cls": cls, **setters}
    exec(source, namespace)  # generated from the field names of our own table, as dataclasses does
    build: typing.Callable[[tuple[Any, ...]], Any] = namespace["build"]
    return build


def _check_id_range(msg_id: int, direction: Direction, name: str) -> None:
    if msg_id <= 0x1F:
        return
    expected = Direction.AGENT_TO_GROUND if msg_id <= 0x7F else Direction.GROUND_TO_AGENT
    if direction != expected:
        raise ValueError(f"{name}: id 0x{msg_id:02X} lies in the {expected} range")


def message_class(msg_id: int) -> type[Message]:
    try:
        return _BY_ID[msg_id]
    except KeyError:
        raise UnknownMessageError(f"no message with id 0x{msg_id:02X}") from None


def message_class_by_name(name: str) -> type[Message]:
    try:
        return _BY_NAME[name.upper()]
    except KeyError:
        raise UnknownMessageError(f"no message named {name!r}") from None


def message_classes() -> Mapping[int, type[Message]]:
    """Every message class by id (a read-only view of the table)."""
    return MappingProxyType(_BY_ID)


def known_ids() -> frozenset[int]:
    return frozenset(_BY_ID)


def definitions() -> tuple[MessageDef, ...]:
    """The whole table, in id order."""
    return tuple(_BY_ID[i].DEFINITION for i in sorted(_BY_ID))


# Fields appended in 1.3 (SPEC.md s. 14): without them the table is 1.0-1.2's, whose hash a 1.3 ground accepts
# (a shorter payload zero-extends, so a 1.2 agent's `generation` reads 0, "not sent").
ADDED_IN_1_3 = frozenset({("HELLO", "generation"), ("HEARTBEAT", "generation"),
                          ("EPISODE_START", "generation"), ("EPISODE_END", "generation")})


def canonical_description(before_1_3: bool = False) -> str:
    """The text the definition hash is computed from: one line per message, one per field (1.2's table if asked)."""
    lines = []
    for d in definitions():
        lines.append(f"{d.msg_id:02X} {d.name} {d.direction.name} ack={int(d.needs_ack)}")
        lines.extend(f"  {f.offset} {f.name} {f.wire.spec_name}" for f in d.fields
                     if not (before_1_3 and (d.name, f.name) in ADDED_IN_1_3))
    return "\n".join(lines) + "\n"


def definitions_hash(before_1_3: bool = False) -> int:
    """First 4 bytes (little-endian u32) of SHA-256 over canonical_description(); sent in HELLO.

    before_1_3: the hash a 1.0, 1.1 or 1.2 peer sends (0x69BE26C5), which a 1.3 ground still talks to.
    """
    digest = hashlib.sha256(canonical_description(before_1_3).encode()).digest()
    return int.from_bytes(digest[:4], "little")
