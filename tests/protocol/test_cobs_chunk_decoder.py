"""CobsChunkDecoder, the receivers' fast COBS: the same bytes and the same errors as cobs_decode, always."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocol.cobs import CobsChunkDecoder, cobs_decode, cobs_encode
from protocol.errors import CobsError

# Few distinct byte values so that chains repeat and the cached path runs as often as the walk.
_FRAMES = st.lists(st.binary(max_size=300).map(lambda b: bytes(x % 3 for x in b)), max_size=40)
# Chunks that are mostly not valid COBS: codes running past the end, zeros inside, full blocks.
_CHUNKS = st.lists(st.binary(max_size=300).map(lambda b: bytes((x % 5) * 60 for x in b)), max_size=40)


def _decoded_or_error(decode: object, chunk: bytes) -> bytes | str:
    try:
        return decode(chunk)  # type: ignore[operator, no-any-return]
    except CobsError:
        return "CobsError"


@settings(max_examples=150, deadline=None)
@given(frames=_FRAMES)
def test_chunks_of_valid_frames_decode_to_the_frames(frames: list[bytes]) -> None:
    decoder = CobsChunkDecoder(max_patterns=8)
    for frame in frames + frames:  # each chain both learned and reused
        assert decoder.decode(cobs_encode(frame)) == frame


@settings(max_examples=150, deadline=None)
@given(valid=_FRAMES, chunks=_CHUNKS)
def test_any_chunk_gives_what_cobs_decode_gives(valid: list[bytes], chunks: list[bytes]) -> None:
    decoder = CobsChunkDecoder(max_patterns=8)
    encoded = [cobs_encode(frame) for frame in valid]
    for chunk in encoded + chunks + encoded + chunks:
        assert _decoded_or_error(decoder.decode, chunk) == _decoded_or_error(cobs_decode, chunk)


def test_a_chunk_with_the_known_codes_but_other_data_keeps_its_data() -> None:
    decoder = CobsChunkDecoder()
    first, second = b"\x01\x00\x02\x03", b"\x07\x00\x08\x09"
    assert decoder.decode(cobs_encode(first)) == first
    assert decoder.decode(cobs_encode(second)) == second  # by the chain learned from `first`


@pytest.mark.parametrize(("valid", "malformed"), [
    (b"\x03\x01\x01", b"\x03\x01\x00"),  # a zero inside
    (b"\x02\x01\x01", b"\x02\x01\x05"),  # a code that runs past the end
])
def test_a_malformed_chunk_is_refused_where_a_valid_one_of_its_length_and_first_code_was_seen(
        valid: bytes, malformed: bytes) -> None:
    decoder = CobsChunkDecoder()
    assert decoder.decode(valid) == cobs_decode(valid)
    with pytest.raises(CobsError):
        decoder.decode(malformed)


def test_a_length_whose_chains_keep_changing_is_decoded_plainly_and_alike() -> None:
    decoder = CobsChunkDecoder()
    # Same length and first code, a zero moving through the rest: a new chain every chunk (as learning SAMPLEs).
    frames = [b"\x01\x02\x03" + bytes(1 if i != j else 0 for i in range(20)) for j in range(20)] * 3
    for frame in frames:
        assert decoder.decode(cobs_encode(frame)) == frame
    malformed = bytearray(cobs_encode(frames[0]))
    malformed[4] = 0xFE  # the second code runs past the end; the same length and first code
    with pytest.raises(CobsError):
        cobs_decode(bytes(malformed))
    with pytest.raises(CobsError):
        decoder.decode(bytes(malformed))
