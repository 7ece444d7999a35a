"""COBS against the reference `cobs` package, beyond the basic edge cases; CRC against a bitwise reference."""

from __future__ import annotations

import pytest
from cobs import cobs as reference_cobs
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol.cobs import cobs_decode, cobs_encode
from protocol.crc import crc16_ccitt_false
from protocol.errors import CobsError

EDGES = {
    "zeros-254": bytes(254),
    "zeros-255": bytes(255),
    "nonzero-254-then-zeros": b"\x07" * 254 + bytes(2),
    "zero-then-nonzero-254": b"\x00" + b"\x07" * 254,
    "nonzero-508": bytes(range(1, 255)) * 2,
    "nonzero-509": bytes(range(1, 255)) * 2 + b"\x01",
    "ends-with-zero": b"\x11\x22\x00",
}


@pytest.mark.parametrize("data", EDGES.values(), ids=EDGES.keys())
def test_cobs_edge_cases_match_the_reference(data: bytes) -> None:
    assert cobs_encode(data) == reference_cobs.encode(data)
    assert cobs_decode(reference_cobs.encode(data)) == data


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600) | st.lists(st.sampled_from([0, 1, 255]), max_size=600).map(bytes))
def test_cobs_matches_the_reference_on_any_bytes(data: bytes) -> None:
    encoded = cobs_encode(data)
    assert encoded == reference_cobs.encode(data)
    assert b"\x00" not in encoded
    assert cobs_decode(encoded) == data


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=300))
def test_cobs_decode_raises_only_cobs_error_and_agrees_with_the_reference(chunk: bytes) -> None:
    try:
        ours: bytes | None = cobs_decode(chunk)
    except CobsError:
        ours = None
    try:
        theirs: bytes | None = reference_cobs.decode(chunk)
    except reference_cobs.DecodeError:
        theirs = None
    assert ours == theirs


def _crc_bitwise(data: bytes) -> int:
    crc = 0xFFFF
    for byte in data:
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021 if crc & 0x8000 else crc << 1) & 0xFFFF
    return crc


def test_crc_check_value_and_empty_input() -> None:
    assert crc16_ccitt_false(b"123456789") == 0x29B1
    assert crc16_ccitt_false(b"") == 0xFFFF


@settings(max_examples=100, deadline=None)
@given(st.binary(max_size=300))
def test_crc_matches_the_bitwise_c_routine_of_spec_md(data: bytes) -> None:
    assert crc16_ccitt_false(data) == _crc_bitwise(data)
