"""Generates SPEC.md section 3 (message tables, enumerations, hash) and the parameter table of section 13.

`python -m protocol.spec` rewrites the parts of protocol/SPEC.md between the GENERATED markers;
`python -m protocol.spec --check` exits 1 if SPEC.md is out of date. Rendering is pure; only main() touches files.
"""

from __future__ import annotations

import sys
from enum import IntEnum, IntFlag
from pathlib import Path

from protocol import messages as _messages  # noqa: F401  (registers every message in the table)
from protocol.enums import AckResult, Action, DumpKind, EndReason, Mode, NodeKind, ParamType, Severity
from protocol.parameters import PARAMS, ParamDef, f32
from protocol.registry import MAX_PAYLOAD, MessageDef, definitions, definitions_hash

BEGIN = (
    "<!-- BEGIN GENERATED MESSAGE TABLES: `python -m protocol.spec` rewrites this part from protocol/messages.py -->"
)
END = "<!-- END GENERATED MESSAGE TABLES -->"
PARAM_BEGIN = (
    "<!-- BEGIN GENERATED PARAMETER TABLE: `python -m protocol.spec` rewrites this part from protocol/parameters.py -->"
)
PARAM_END = "<!-- END GENERATED PARAMETER TABLE -->"
SPEC_PATH = Path(__file__).with_name("SPEC.md")

# The enumerations a firmware author needs, in the order SPEC.md lists them.
ENUMS: tuple[type[IntEnum], ...] = (Mode, Action, EndReason, AckResult, Severity, DumpKind, ParamType, NodeKind)


def _cell(text: str) -> str:
    """Text safe inside a Markdown table cell."""
    return text.replace("|", "\\|").replace("\n", " ")


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def _payload_size(d: MessageDef) -> str:
    if d.has_tail:
        room = MAX_PAYLOAD - d.fixed_size
        return f"{d.fixed_size} bytes + `{d.fields[-1].name}` (0 to {room} bytes), at most {MAX_PAYLOAD}"
    return f"{d.fixed_size} bytes"


def render_message(d: MessageDef) -> str:
    """One message: heading, properties, doc, field table and payload size."""
    lines = [
        f"### 0x{d.msg_id:02X} {d.name}",
        "",
        f"id `0x{d.msg_id:02X}` ({d.msg_id}) · direction: {d.direction.value} · "
        f"ACK needed: {_yes(d.needs_ack)} · chunked: {_yes(d.chunked)}",
        "",
        d.doc,
        "",
    ]
    if d.fields:
        lines += ["| offset | size | type | field | unit | meaning |", "|---|---|---|---|---|---|"]
        for f in d.fields:
            size = str(f.wire.size) if not f.wire.is_tail else "rest"
            lines.append(
                f"| {f.offset} | {size} | `{f.wire.spec_name}` | `{f.name}` | {_cell(f.unit)} | {_cell(f.doc)} |"
            )
        lines.append("")
    else:
        lines += ["No fields.", ""]
    lines += [f"Payload: {_payload_size(d)}.", ""]
    return "\n".join(lines)


def render_summary(defs: tuple[MessageDef, ...]) -> str:
    lines = [
        "| id | name | direction | ACK needed | chunked | payload bytes |",
        "|---|---|---|---|---|---|",
    ]
    for d in defs:
        size = f"{d.fixed_size} + tail" if d.has_tail else str(d.fixed_size)
        lines.append(
            f"| `0x{d.msg_id:02X}` | [{d.name}](#0x{d.msg_id:02x}-{d.name.lower()}) "
            f"| {d.direction.value} | {_yes(d.needs_ack)} | {_yes(d.chunked)} | {size} |"
        )
    return "\n".join(lines) + "\n"


def render_enum(enum: type[IntEnum] | type[IntFlag]) -> str:
    own_doc = enum.__dict__.get("__doc__") or ""
    doc = own_doc.strip().splitlines()[0] if own_doc.strip() else ""
    lines = [f"**{enum.__name__}**" + (f" — {_cell(doc)}" if doc else ""), "", "| value | name |", "|---|---|"]
    lines += [f"| {member.value} | `{member.name}` |" for member in enum]
    return "\n".join(lines) + "\n"


def render_section() -> str:
    """Everything between the markers (the markers excluded)."""
    defs = definitions()
    value = definitions_hash()
    parts = [
        f"**Definitions hash** of this table (section 8): `0x{value:08X}` (decimal {value}). "
        "It goes into HELLO's `definitions_hash`.",
        "",
        "Offsets are in bytes from the start of the payload (the payload starts at inner byte 5). "
        "A `rest` field takes every remaining payload byte and may be empty.",
        "",
        render_summary(defs),
    ]
    parts += [render_message(d) for d in defs]
    parts += ["### Enumerations", "", "Values of the fields that hold an enumeration.", ""]
    parts += [render_enum(e) for e in ENUMS]
    return "\n".join(parts)


def _number(value: float, kind: ParamType) -> str:
    if kind != ParamType.F32:
        return str(int(value))
    for digits in range(1, 10):  # the shortest decimal whose nearest f32 is the stored value
        text = f"{value:.{digits}g}"
        if f32(float(text)) == value:
            return text
    return repr(value)


def render_param(p: ParamDef) -> str:
    refused = ", ".join(m.name for m in p.refused_in) or "never"
    high = _number(p.maximum, p.param_type)
    if p.simulator_only:
        high += f" (real agent: {_number(p.firmware_range()[1], p.param_type)})"
    doc = f"*optional*: {p.doc}" if p.optional and not p.simulator_only else p.doc
    return (
        f"| {p.index} | `{p.name}` | {p.param_type.name} | {_cell(p.unit)} | {_number(p.default, p.param_type)} "
        f"| {_number(p.minimum, p.param_type)} | {high} | {refused} | {'yes' if p.learner else 'no'} | {_cell(doc)} |"
    )


def render_params() -> str:
    """The parameter table (between the PARAM markers)."""
    lines = [
        f"{len(PARAMS)} parameters. An `F32` figure below is the shortest decimal whose nearest f32 is the stored "
        "value; PARAM_VALUE carries that f32 widened exactly to f64 (0.4 goes out as 0.4000000059604645). "
        "\"refused in\": modes in which PARAM_SET is answered NOT_ALLOWED_IN_MODE; "
        "\"learner\": a change restarts the learner as CMD_RESET_MODEL does and is "
        "checked against the RAM budget. *optional*: an agent that does not implement it reports minimum = "
        "maximum = its default (section 13, optional parameters).",
        "",
        "| index | name | type | unit | default | min | max | refused in | learner | meaning |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    lines += [render_param(p) for p in PARAMS]
    return "\n".join(lines) + "\n"


def _replace_between(text: str, begin: str, end: str, body: str) -> str:
    try:
        head, rest = text.split(begin, 1)
        _, tail = rest.split(end, 1)
    except ValueError:
        raise ValueError(f"SPEC.md lacks the markers {begin[:40]}... and {end}") from None
    return f"{head}{begin}\n\n{body}\n{end}{tail}"


def regenerate(spec_text: str) -> str:
    """`spec_text` with the generated parts replaced by the current tables."""
    text = _replace_between(spec_text, BEGIN, END, render_section())
    return _replace_between(text, PARAM_BEGIN, PARAM_END, render_params())


def main(argv: list[str]) -> int:
    current = SPEC_PATH.read_text(encoding="utf-8")
    updated = regenerate(current)
    if "--check" in argv:
        if updated != current:
            print("protocol/SPEC.md is out of date: run `python -m protocol.spec`", file=sys.stderr)
            return 1
        return 0
    if updated != current:
        SPEC_PATH.write_text(updated, encoding="utf-8")
        print(f"rewrote {SPEC_PATH}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
