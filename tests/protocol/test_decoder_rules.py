"""The decoder's rules a user sees: reject counters by cause, append-only payloads, sequence gap counting."""

from __future__ import annotations

import pytest

from protocol import FrameEncoder, FrameFlag, StreamDecoder
from protocol.cobs import cobs_encode
from protocol.crc import crc16_ccitt_false
from protocol.messages import Ack, Sample, Stop, Text

SAMPLE = Sample(t_us=5, sample=9, episode=2, step=3, depth_m=-0.25, velocity_mps=0.5, state=7, action=1, mode=1)
COUNTERS = ("cobs_errors", "runts", "crc_errors", "incompatible", "unknown_id", "oversize", "malformed")


def _frame(inner_without_crc: bytes) -> bytes:
    """Wire bytes of an arbitrary inner frame, with a correct CRC."""
    crc = crc16_ccitt_false(inner_without_crc)
    return cobs_encode(inner_without_crc + crc.to_bytes(2, "big")) + b"\x00"


_GOOD_INNER = bytes([1, 0, 0, 0, 0x20]) + SAMPLE.pack()
_crc_damaged = bytearray(_GOOD_INNER + crc16_ccitt_false(_GOOD_INNER).to_bytes(2, "big"))
_crc_damaged[10] ^= 0x40

REJECTS = {
    "cobs_errors": b"\x05\x01\x02\x00",  # the code promises 4 data bytes, the chunk holds 2
    "runts": cobs_encode(bytes([1, 0, 0, 0, 0x20, 0])) + b"\x00",  # 6 bytes: one short of the empty frame
    "crc_errors": cobs_encode(bytes(_crc_damaged)) + b"\x00",
    "incompatible": _frame(bytes([2, 0, 0, 0, 0x20]) + SAMPLE.pack()),  # protocol version 2
    "unknown_id": _frame(bytes([1, 0, 0, 0, 0x7F])),
    "oversize": bytes(range(1, 256)) + bytes(range(1, 50)) + b"\x00",  # 304 bytes before the delimiter
}


@pytest.mark.parametrize("cause", sorted(REJECTS))
def test_each_reject_is_counted_under_its_cause_and_the_next_frame_decodes(cause: str) -> None:
    decoder = StreamDecoder()
    good = FrameEncoder(100).encode(SAMPLE).wire
    frames = decoder.feed(REJECTS[cause] + good)
    assert [f.message for f in frames] == [SAMPLE]
    counts = decoder.stats.as_dict()
    assert {name: counts[name] for name in COUNTERS} == {name: int(name == cause) for name in COUNTERS}
    assert decoder.stats.rejects == 1


def test_an_oversize_chunk_arriving_in_many_pieces_is_counted_once() -> None:
    decoder = StreamDecoder()
    for _ in range(50):
        assert decoder.feed(b"\x55" * 100) == []
    assert [f.seq for f in decoder.feed(b"\x00" + FrameEncoder(3).encode(SAMPLE).wire)] == [3]
    assert decoder.stats.oversize == 1 and decoder.stats.rejects == 1


@pytest.mark.parametrize("bit", range(5, 8))  # bit 4 is SIGNED since 1.1
def test_an_unknown_incompatible_flag_drops_the_frame(bit: int) -> None:
    decoder = StreamDecoder()
    assert decoder.feed(_frame(bytes([1, 1 << bit, 0, 0, 0x20]) + SAMPLE.pack())) == []
    assert decoder.stats.incompatible == 1


def test_unknown_compatible_flags_are_ignored_and_kept() -> None:
    flags = 0x08 | FrameFlag.REPLAYED
    frames = StreamDecoder().feed(_frame(bytes([1, flags, 0x34, 0x12, 0x20]) + SAMPLE.pack()))
    assert [(f.flags, f.seq, f.message) for f in frames] == [(flags, 0x1234, SAMPLE)]


def test_a_short_payload_is_zero_extended() -> None:
    payload = SAMPLE.pack()[:24]  # t_us, sample, episode, step and pressure: an older sender's layout
    [frame] = StreamDecoder().feed(FrameEncoder().encode_payload(Sample.MSG_ID, payload).wire)
    assert frame.message == Sample(t_us=5, sample=9, episode=2, step=3)


def test_extra_trailing_bytes_are_ignored() -> None:
    payload = SAMPLE.pack() + b"\x01\x02\x03 newer fields"
    [frame] = StreamDecoder().feed(FrameEncoder().encode_payload(Sample.MSG_ID, payload).wire)
    assert frame.message == SAMPLE


def test_an_empty_payload_decodes_to_all_defaults() -> None:
    [frame] = StreamDecoder().feed(FrameEncoder().encode_payload(Text.MSG_ID, b"").wire)
    assert frame.message == Text(t_us=0, severity=0, text="")


def test_commands_request_an_ack() -> None:
    [frame] = StreamDecoder().feed(FrameEncoder().encode(Stop()).wire)
    assert frame.flags & FrameFlag.ACK_REQUESTED
    [frame] = StreamDecoder().feed(FrameEncoder().encode(Ack(cmd_msg_id=0x81)).wire)
    assert not frame.flags & FrameFlag.ACK_REQUESTED


def _feed_seqs(seqs: list[int]) -> StreamDecoder:
    decoder = StreamDecoder()
    for seq in seqs:
        assert len(decoder.feed(FrameEncoder(seq).encode(SAMPLE).wire)) == 1
    return decoder


@pytest.mark.parametrize(
    ("seqs", "lost", "duplicates"),
    [
        ([0, 1, 2, 3], 0, 0),
        ([0, 1, 5, 6], 3, 0),
        ([65533, 65534, 65535, 0, 1], 0, 0),  # wrap-around is not loss
        ([65534, 1], 2, 0),  # 65535 and 0 missing across the wrap
        ([10, 10], 0, 1),  # a retry with the same seq is a duplicate, not 65535 lost frames
        ([10, 11, 10, 12], 0, 1),  # a late retry does not move the expectation back
        ([10, 11, 12, 5, 13], 0, 1),  # reordered / late
        ([0, 30000], 29999, 0),  # under half the range ahead: loss
        ([0, 40000], 0, 1),  # over half the range ahead: taken as a late frame
    ],
)
def test_sequence_gaps_are_counted_as_lost_frames(seqs: list[int], lost: int, duplicates: int) -> None:
    stats = _feed_seqs(seqs).stats
    assert (stats.lost, stats.duplicates, stats.frames) == (lost, duplicates, len(seqs))


def test_reset_sequence_forgets_the_expected_seq_after_a_peer_restart() -> None:
    decoder = _feed_seqs([100, 101])
    decoder.reset_sequence()
    decoder.feed(FrameEncoder(0).encode(SAMPLE).wire)
    assert (decoder.stats.lost, decoder.stats.duplicates) == (0, 0)


def test_a_frame_with_a_bad_crc_does_not_count_as_lost_twice() -> None:
    decoder = _feed_seqs([0])
    inner = bytearray([1, 0, 1, 0, 0x20]) + SAMPLE.pack()
    inner += crc16_ccitt_false(bytes(inner)).to_bytes(2, "big")
    inner[12] ^= 0x01  # seq 1 arrives damaged
    damaged = cobs_encode(bytes(inner)) + b"\x00"
    assert decoder.feed(damaged + FrameEncoder(2).encode(SAMPLE).wire)[0].seq == 2
    assert (decoder.stats.lost, decoder.stats.crc_errors) == (1, 1)
