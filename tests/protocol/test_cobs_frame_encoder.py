"""CobsFrameEncoder, the agent's fast COBS: the same wire bytes as cobs_encode plus the delimiter, always."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from protocol.cobs import CobsFrameEncoder, cobs_decode, cobs_encode

# Few distinct byte values so that zero patterns repeat and the cached path runs as often as the first.
_FRAMES = st.lists(st.binary(max_size=300).map(lambda b: bytes(x % 3 for x in b)), max_size=40)


@settings(max_examples=150, deadline=None)
@given(frames=_FRAMES)
def test_wire_bytes_equal_cobs_encode_with_the_delimiter(frames: list[bytes]) -> None:
    encoder = CobsFrameEncoder(max_patterns=8)
    for frame in frames + frames:  # each pattern both learned and reused
        wire = encoder.encode(frame)
        assert wire == cobs_encode(frame) + b"\x00"
        assert cobs_decode(wire[:-1]) == frame


def test_frames_sharing_a_zero_pattern_keep_their_own_bytes() -> None:
    encoder = CobsFrameEncoder()
    first, second = b"\x01\x00\x02\x03\x00", b"\x07\x00\x08\x09\x00"
    assert encoder.encode(first) == cobs_encode(first) + b"\x00"
    assert encoder.encode(second) == cobs_encode(second) + b"\x00"  # from the cached codes of `first`
    assert encoder.encode(second) != encoder.encode(first)
