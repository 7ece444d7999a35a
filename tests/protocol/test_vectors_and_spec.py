"""The golden vectors and SPEC.md agree with the code, in both directions."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from typing import Any

import pytest

from protocol import FrameEncoder, StreamDecoder, definitions, definitions_hash, message_class_by_name
from protocol.cobs import cobs_decode
from protocol.spec import SPEC_PATH, regenerate
from tests.vectors.generate import VECTORS_PATH

VECTORS: list[dict[str, Any]] = [json.loads(line) for line in VECTORS_PATH.read_text(encoding="utf-8").splitlines()]
SPEC_TEXT = SPEC_PATH.read_text(encoding="utf-8")


def _id(vector: dict[str, Any]) -> str:
    return f"{vector['name']}-seq{vector['seq']}"


@pytest.mark.parametrize("vector", VECTORS, ids=_id)
def test_fields_encode_to_the_golden_bytes(vector: dict[str, Any]) -> None:
    message = message_class_by_name(vector["name"]).from_dict(vector["fields"])
    encoded = FrameEncoder(first_seq=vector["seq"]).encode(message, vector["flags"])
    assert encoded.wire.hex() == vector["wire_hex"]
    assert cobs_decode(encoded.wire[:-1]).hex() == vector["inner_hex"]


@pytest.mark.parametrize("vector", VECTORS, ids=_id)
def test_golden_bytes_decode_to_the_fields(vector: dict[str, Any]) -> None:
    frames = StreamDecoder().feed(bytes.fromhex(vector["wire_hex"]))
    assert len(frames) == 1
    frame = frames[0]
    assert frame.message.DEFINITION.name == vector["name"]
    assert frame.message.to_dict() == vector["fields"]
    assert (frame.flags, frame.seq, frame.inner.hex()) == (vector["flags"], vector["seq"], vector["inner_hex"])


def test_every_message_in_the_table_has_a_golden_vector() -> None:
    assert {d.name for d in definitions()} <= {v["name"] for v in VECTORS}


def test_spec_md_is_generated_from_the_current_table() -> None:
    assert regenerate(SPEC_TEXT) == SPEC_TEXT, "SPEC.md is out of date: run `python -m protocol.spec`"


_DIRECTIONS = {"agent → ground": "AGENT_TO_GROUND", "ground → agent": "GROUND_TO_AGENT", "both": "BOTH"}


def _hash_from_spec_tables(spec: str) -> int:
    """Section 8's recipe, applied to the tables of section 3 as a firmware author reads them."""
    lines: list[str] = []
    for block in re.split(r"^### ", spec.split("## 3. Messages", 1)[1].split("## 4.", 1)[0], flags=re.M)[1:]:
        heading = re.match(r"0x([0-9A-F]{2}) (\w+)\n", block)
        if heading is None:  # the enumerations
            continue
        props = re.search(r"direction: (.+?) · ACK needed: (yes|no)", block)
        assert props is not None
        lines.append(f"{heading[1]} {heading[2]} {_DIRECTIONS[props[1]]} ack={int(props[2] == 'yes')}\n")
        for row in re.finditer(r"^\| (\d+) \| (?:\d+|rest) \| `([^`]+)` \| `(\w+)` \|", block, flags=re.M):
            lines.append(f"  {row[1]} {row[3]} {row[2]}\n")
    return int.from_bytes(hashlib.sha256("".join(lines).encode()).digest()[:4], "little")


def test_definitions_hash_follows_the_spec_recipe_and_matches_the_printed_value() -> None:
    printed = re.search(r"\*\*Definitions hash\*\* of this table \(section 8\): `0x([0-9A-F]{8})`", SPEC_TEXT)
    assert printed is not None
    assert _hash_from_spec_tables(SPEC_TEXT) == definitions_hash() == int(printed[1], 16)


def test_spec_tables_list_every_field_of_every_message() -> None:
    for d in definitions():
        block = SPEC_TEXT.split(f"### 0x{d.msg_id:02X} {d.name}\n", 1)[1].split("\n### ", 1)[0]
        for f in d.fields:
            assert f"| {f.offset} | " in block and f"`{f.name}`" in block and f"`{f.wire.spec_name}`" in block


def test_vectors_file_is_what_the_generator_writes() -> None:
    from tests.vectors.generate import render

    assert render() == VECTORS_PATH.read_text(encoding="utf-8")


def test_vectors_path_is_inside_the_tests() -> None:
    assert Path(VECTORS_PATH).parent.name == "vectors"
