"""Frame, CRC and COBS basics of wire-frame.md."""

from __future__ import annotations

import pytest
from cobs import cobs as reference_cobs

from protocol.cobs import cobs_decode, cobs_encode
from protocol.crc import crc16_ccitt_false
from protocol.decoder import StreamDecoder
from protocol.encoder import FrameEncoder
from protocol.errors import CobsError
from protocol.messages import Sample, Text


def test_crc_check_value() -> None:
    assert crc16_ccitt_false(b"123456789") == 0x29B1


@pytest.mark.parametrize(
    "data",
    [b"", b"\x00", b"\x00" * 10, b"\x01" * 253, b"\x01" * 254, b"\x01" * 255, b"\x01" * 254 + b"\x00"],
    ids=["empty", "one-zero", "all-zeros", "253", "254", "255", "254-then-zero"],
)
def test_cobs_matches_the_reference_package_on_edge_cases(data: bytes) -> None:
    assert cobs_encode(data) == reference_cobs.encode(data)
    assert cobs_decode(cobs_encode(data)) == data


def test_cobs_rejects_a_code_running_past_the_chunk() -> None:
    with pytest.raises(CobsError):
        cobs_decode(b"\x05\x01\x02")


def test_a_frame_survives_the_round_trip_with_its_sequence_number() -> None:
    encoder, decoder = FrameEncoder(first_seq=65535), StreamDecoder()
    sample = Sample(t_us=10, sample=3, depth_m=0.5, state=42, action=1, mode=1)
    wire = encoder.encode(sample).wire + encoder.encode(Text(severity=1, text="hello")).wire
    frames = decoder.feed(wire)
    assert [f.seq for f in frames] == [65535, 0]
    assert frames[0].message == Sample.unpack(sample.pack())
    assert frames[1].message.text == "hello"  # type: ignore[attr-defined]
    assert decoder.stats.lost == 0
