"""Columnar decode of recorded frames (replay) agrees with decoding frame by frame."""

from __future__ import annotations

import numpy as np

from groundstation.recording.columns import message_array
from protocol import FrameEncoder, StreamDecoder
from protocol.columns import columns, payload_records
from protocol.messages import Sample, Text

SAMPLES = [Sample(t_us=10 * i, sample=i, depth_m=0.25 * i, velocity_mps=-0.5, state=i, action=i % 2) for i in range(5)]


def _inners() -> list[bytes]:
    encoder = FrameEncoder()
    wire = b"".join(encoder.encode(m).wire for m in [SAMPLES[0], Text(text="x"), *SAMPLES[1:]])
    wire += encoder.encode_payload(Sample.MSG_ID, SAMPLES[0].pack()[:20]).wire  # an older, shorter SAMPLE
    inners = [f.inner for f in StreamDecoder().feed(wire)]
    damaged = bytearray(inners[2])
    damaged[9] ^= 0xFF  # a recorded frame with a bad CRC is skipped
    return [*inners, bytes(damaged)]


def test_columns_hold_the_fields_of_every_valid_frame_of_the_message() -> None:
    definition = Sample.DEFINITION
    cols = columns(payload_records(_inners(), definition), definition)
    assert list(cols["sample"]) == [0, 1, 2, 3, 4, 0]
    assert list(cols["depth_m"]) == [m.depth_m for m in SAMPLES] + [0.0]  # zero-extended
    assert list(cols["t_us"]) == [m.t_us for m in SAMPLES] + [0]


def test_numpy_array_matches_the_frame_by_frame_decode() -> None:
    array = message_array(_inners(), Sample.DEFINITION)
    assert array.shape == (6,)
    np.testing.assert_array_equal(array["state"][:5], [m.state for m in SAMPLES])
    np.testing.assert_array_equal(array["velocity_mps"][:5], np.float32(-0.5))
    assert array["depth_m"].dtype == np.dtype("<f4")
