"""Wire field types: each annotated Python type carries its little-endian layout, unit and meaning."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Annotated, Any


@dataclass(frozen=True)
class WireType:
    """How one field is laid out on the wire."""

    spec_name: str  # as SPEC.md names it: u8, i32, f32, char[24], bytes[], text[]
    struct_code: str  # the `struct` code; "" for the variable-length tail
    size: int  # bytes on the wire; 0 for the tail, which takes the rest of the payload
    json_type: str  # "integer", "number", "string"
    minimum: float | None = None
    maximum: float | None = None

    @property
    def is_tail(self) -> bool:
        return self.size == 0

    @property
    def is_text(self) -> bool:
        # not json_type: bytes[] is a JSON string too (hex), but on the wire it is raw bytes, not UTF-8
        return self.spec_name.startswith(("char[", "text["))


def _int(spec: str, code: str, size: int, signed: bool) -> WireType:
    bits = 8 * size
    low, high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signed else (0, 2**bits - 1)
    return WireType(spec, code, size, "integer", low, high)


U8_WIRE = _int("u8", "B", 1, signed=False)
U16_WIRE = _int("u16", "H", 2, signed=False)
U32_WIRE = _int("u32", "I", 4, signed=False)
U64_WIRE = _int("u64", "Q", 8, signed=False)
I8_WIRE = _int("i8", "b", 1, signed=True)
I16_WIRE = _int("i16", "h", 2, signed=True)
I32_WIRE = _int("i32", "i", 4, signed=True)
I64_WIRE = _int("i64", "q", 8, signed=True)
F32_WIRE = WireType("f32", "f", 4, "number")
F64_WIRE = WireType("f64", "d", 8, "number")
# 24 bytes: parameter names such as `surface_on_link_loss` (20) must fit; 16 truncated them.
NAME_WIRE = WireType("char[24]", "24s", 24, "string")  # UTF-8, NUL-padded, NUL-terminated if shorter
TAIL_BYTES_WIRE = WireType("bytes[]", "", 0, "string")  # rest of the payload (hex in JSON)
TAIL_TEXT_WIRE = WireType("text[]", "", 0, "string")  # rest of the payload, UTF-8

U8 = Annotated[int, U8_WIRE]
U16 = Annotated[int, U16_WIRE]
U32 = Annotated[int, U32_WIRE]
U64 = Annotated[int, U64_WIRE]
I8 = Annotated[int, I8_WIRE]
I16 = Annotated[int, I16_WIRE]
I32 = Annotated[int, I32_WIRE]
I64 = Annotated[int, I64_WIRE]
F32 = Annotated[float, F32_WIRE]
F64 = Annotated[float, F64_WIRE]
Name = Annotated[str, NAME_WIRE]
TailBytes = Annotated[bytes, TAIL_BYTES_WIRE]
TailText = Annotated[str, TAIL_TEXT_WIRE]


def wire(doc: str, unit: str = "", default: Any = 0) -> Any:
    """A message field: its meaning and unit for SPEC.md and the JSON schema; zero by default,
    which is also what a receiver reads when an older sender's payload is shorter."""
    return dataclasses.field(default=default, metadata={"doc": doc, "unit": unit})
