"""The compiled frame path (protocol/fast_frames.py) gives byte for byte what the stdlib codec gives."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from protocol import FrameEncoder, StreamDecoder, compiled, encoder
from protocol import decoder as decoder_module
from protocol.chunk_verdicts import CHUNK_COBS_ERROR, CHUNK_OK
from protocol.cobs import cobs_decode, cobs_encode
from protocol.enums import INCOMPATIBLE_FLAGS_MASK, PROTOCOL_VERSION
from protocol.errors import CobsError
from protocol.fast_frames import COMPILED_MAX_PAYLOAD, decode_buffer, frame_writer
from protocol.frame import build_inner
from tests.protocol.strategies import any_message

# The compiled path loads in the background; these tests compare it, so it must be there.
assert compiled.wait(300), "numba is a dependency: the compiled path must load"

# Streams of good frames, garbage and stray delimiters, cut into reads of any size.
_pieces = st.lists(st.one_of(
    any_message.map(lambda m: FrameEncoder(compiled=False).encode(m).wire),
    st.binary(max_size=300),
    st.just(b"\x00"),
), max_size=12)


@settings(max_examples=300, deadline=None)
@given(pieces=_pieces, cuts=st.lists(st.integers(1, 600), max_size=8), agent=st.booleans())
def test_the_compiled_decoder_gives_the_frames_and_counts_of_the_stdlib_decoder(
        pieces: list[bytes], cuts: list[int], agent: bool) -> None:
    stream = b"".join(pieces)
    results = []
    threshold = decoder_module.COMPILED_FROM_BYTES
    decoder_module.COMPILED_FROM_BYTES = 0  # every read on the compiled path, however short
    try:
        for compiled in (False, True):
            decoder = StreamDecoder(compiled=compiled, agent=agent)
            frames, at = [], 0
            for cut in [*cuts, len(stream)]:
                frames += decoder.feed(stream[at : at + cut])
                at += cut
            frames += decoder.feed(stream[at:])
            results.append((frames, decoder.stats.as_dict(), decoder.buffered_bytes))
    finally:
        decoder_module.COMPILED_FROM_BYTES = threshold
    assert results[0] == results[1]


@settings(max_examples=300, deadline=None)
@given(chunk=st.binary(min_size=1, max_size=700).map(lambda b: b.replace(b"\x00", b"\x01")))
def test_compiled_cobs_decoding_matches_the_reference_on_any_chunk(chunk: bytes) -> None:
    rest, table, inner = decode_buffer(chunk + b"\x00", 10_000, 0, PROTOCOL_VERSION, 0)
    assert rest == len(chunk) + 1 and len(table) == 1
    start, length, verdict = table[0][:3]
    try:
        expected = cobs_decode(chunk)
    except CobsError:
        assert verdict == CHUNK_COBS_ERROR
        return
    if verdict == CHUNK_OK:  # the CRC residue of random bytes is rarely 0; when it is, the bytes must match
        assert inner[start : start + length] == expected
    else:
        assert verdict != CHUNK_COBS_ERROR


@settings(max_examples=300, deadline=None)
@given(data=st.binary(max_size=600))
def test_compiled_decoding_of_encoded_data_gives_the_data_back(data: bytes) -> None:
    from protocol.crc import crc16_ccitt_false

    inner = data + crc16_ccitt_false(data).to_bytes(2, "big")  # a good CRC, so the bytes come back
    _, table, decoded = decode_buffer(cobs_encode(inner) + b"\x00", 10_000, 0, inner[0] if inner else 0, 0)
    start, length, verdict = table[0][:3]
    assert verdict == CHUNK_OK and decoded[start : start + length] == inner


@settings(max_examples=500, deadline=None)
@given(payload=st.binary(max_size=COMPILED_MAX_PAYLOAD), flags=st.integers(0, 255),
       seq=st.integers(0, 0xFFFF), msg_id=st.integers(0, 255))
def test_the_compiled_writer_gives_the_wire_bytes_of_the_stdlib_encoder(
        payload: bytes, flags: int, seq: int, msg_id: int) -> None:
    expected = cobs_encode(build_inner(flags, seq, msg_id, payload)) + b"\x00"
    assert frame_writer(PROTOCOL_VERSION)(payload, flags, seq, msg_id) == expected


@settings(max_examples=200, deadline=None)
@given(messages=st.lists(any_message, max_size=20), first_seq=st.integers(0, 0xFFFF))
def test_a_compiled_frame_encoder_sends_the_bytes_of_the_stdlib_one(messages: list, first_seq: int) -> None:
    plain, compiled = FrameEncoder(first_seq, compiled=False), FrameEncoder(first_seq)
    assert [plain.encode(m) for m in messages] == [compiled.encode(m) for m in messages]


def test_the_encoder_sends_through_the_compiled_writer_only_what_it_can_take() -> None:
    assert encoder.COMPILED_MAX_PAYLOAD == COMPILED_MAX_PAYLOAD


def test_incompatible_flags_are_rejected_by_the_compiled_check() -> None:
    inner = build_inner(INCOMPATIBLE_FLAGS_MASK & -INCOMPATIBLE_FLAGS_MASK, 1, 0x20, b"")
    _, table, _ = decode_buffer(cobs_encode(inner) + b"\x00", 256, 7, PROTOCOL_VERSION, INCOMPATIBLE_FLAGS_MASK)
    assert table[0][2] != CHUNK_OK
