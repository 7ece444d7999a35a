"""Command signing (SPEC.md section 12): signed frames verify, forged and replayed ones are refused."""

from __future__ import annotations

import hashlib
import hmac
import json
from typing import Any

import pytest

from protocol import FrameEncoder, FrameFlag, StreamDecoder, message_class_by_name
from protocol.cobs import cobs_decode, cobs_encode
from protocol.crc import crc16_ccitt_false
from protocol.errors import FrameError
from protocol.frame import parse_inner
from protocol.messages import DumpChunk, Sample, SetTarget, Stop, Text
from protocol.signing import (
    FUTURE_WINDOW_S,
    LINK_IDS_HELD,
    MARK_AHEAD_S,
    NEW_LINK_WINDOW_S,
    SignatureCheck,
    SignatureVerifier,
    Signer,
    SigningError,
    format_key,
    parse_key,
    timestamp_from_unix_ns,
)
from tests.vectors.generate_signed import SIGNED_VECTORS_PATH, render

KEY = bytes(range(32))
OTHER_KEY = bytes(range(1, 33))
T0_NS = 1_735_689_600 * 10**9  # 2025-01-01 UTC
SIGNED_VECTORS: list[dict[str, Any]] = [json.loads(line) for line in SIGNED_VECTORS_PATH.read_text().splitlines()]


class Clock:
    """A settable wall clock for the signer (ns since the Unix epoch)."""

    def __init__(self, ns: int = T0_NS) -> None:
        self.ns = ns

    def __call__(self) -> int:
        return self.ns


def _inner(wire: bytes) -> bytes:
    return cobs_decode(wire[:-1])


def _with_crc(body: bytes) -> bytes:
    """An inner frame from its bytes before the CRC, with a correct CRC (a forger can always compute it)."""
    return body + crc16_ccitt_false(body).to_bytes(2, "big")


def _signed_wire(message: Any = None, key: bytes = KEY, link_id: int = 1, clock: Clock | None = None,
                 seq: int = 0) -> bytes:
    signer = Signer(key, link_id, clock_ns=clock or Clock())
    return FrameEncoder(seq, signer=signer).encode(message or SetTarget(target_depth_m=1.5)).wire


@pytest.mark.parametrize("vector", SIGNED_VECTORS, ids=lambda v: f"{v['name']}-link{v['link_id']}")
def test_golden_signed_frames_decode_and_verify_with_an_independent_hmac(vector: dict[str, Any]) -> None:
    inner = bytes.fromhex(vector["inner_hex"])
    key = bytes.fromhex(vector["key_hex"])
    signed_part = bytes.fromhex(vector["signed_part_hex"])
    assert hmac.new(key, signed_part, hashlib.sha256).digest()[:6].hex() == vector["signature_hex"]
    assert inner == signed_part + bytes.fromhex(vector["signature_hex"]) + inner[-2:]
    assert signed_part[-7] == vector["link_id"]
    assert int.from_bytes(signed_part[-6:], "little") == vector["timestamp"]
    frames = StreamDecoder().feed(bytes.fromhex(vector["wire_hex"]))
    assert len(frames) == 1 and frames[0].signed and frames[0].flags & FrameFlag.SIGNED
    assert frames[0].message == message_class_by_name(vector["name"]).from_dict(vector["fields"])
    assert SignatureVerifier(key).check(inner, 0.0) is SignatureCheck.VALID


def test_signed_vectors_file_is_what_the_generator_writes() -> None:
    assert render() == SIGNED_VECTORS_PATH.read_text(encoding="utf-8")


def test_a_signed_command_verifies_and_decodes_to_the_same_message() -> None:
    frame = StreamDecoder().feed(_signed_wire())[0]
    assert frame.message == SetTarget(target_depth_m=1.5)
    assert frame.flags == FrameFlag.ACK_REQUESTED | FrameFlag.SIGNED
    assert frame.payload == SetTarget(target_depth_m=1.5).pack()
    assert SignatureVerifier(KEY).check(frame.inner, 0.0) is SignatureCheck.VALID


def test_a_signed_text_tail_keeps_exactly_its_text() -> None:
    """The trailer is cut off before decoding, so a text[] / bytes[] tail does not swallow it."""
    for message in (Text(t_us=3, severity=2, text="tail ✓"), DumpChunk(dump_id=1, kind=1, data=b"\x00\x01")):
        frame = StreamDecoder().feed(_signed_wire(message))[0]
        assert frame.message == message
        assert parse_inner(frame.inner).payload == message.pack()


def test_a_frame_signed_with_another_key_is_refused() -> None:
    verifier = SignatureVerifier(KEY)
    assert verifier.check(_inner(_signed_wire(key=OTHER_KEY)), 0.0) is SignatureCheck.BAD_SIGNATURE
    assert verifier.stats.bad_signature == 1 and verifier.stats.rejects == 1


def test_every_flipped_bit_of_the_signed_bytes_is_refused() -> None:
    inner = _inner(_signed_wire())
    body = inner[:-2]
    for index in range(len(body)):
        for bit in range(8):
            if index == 1 and 1 << bit == FrameFlag.SIGNED:
                continue  # clearing the flag makes the frame unsigned: tested below
            forged = bytearray(body)
            forged[index] ^= 1 << bit
            result = SignatureVerifier(KEY).check(_with_crc(bytes(forged)), 0.0)
            assert result in (SignatureCheck.BAD_SIGNATURE, SignatureCheck.TRUNCATED), (index, bit)


def test_a_truncated_signature_is_refused() -> None:
    body = _inner(_signed_wire())[:-2]
    for cut in range(1, 14):  # part of the signature, then the timestamp and link id too
        assert SignatureVerifier(KEY).check(_with_crc(body[:-cut]), 0.0) is not SignatureCheck.VALID
    assert SignatureVerifier(KEY).check(_with_crc(bytes([1, 0x11, 0, 0, 0x84]) + bytes(5)), 0.0) is (
        SignatureCheck.TRUNCATED)


def test_a_truncated_signed_frame_is_counted_malformed_by_the_decoder() -> None:
    decoder = StreamDecoder()
    assert decoder.feed(cobs_encode(_with_crc(bytes([1, 0x11, 0, 0, 0x84, 1, 2, 3]))) + b"\x00") == []
    assert decoder.stats.malformed == 1


def test_too_new_refused_and_a_link_id_table_of_16_forgets_the_least_recent() -> None:
    verifier = SignatureVerifier(KEY)
    assert verifier.check(_inner(_signed_wire(link_id=0)), 100.0) is SignatureCheck.VALID
    ahead = Clock(T0_NS + int((FUTURE_WINDOW_S + 5) * 1e9))
    assert verifier.check(_inner(_signed_wire(link_id=0, clock=ahead)), 100.0) is SignatureCheck.TOO_NEW
    near = Clock(T0_NS + int((FUTURE_WINDOW_S - 5) * 1e9))
    assert verifier.check(_inner(_signed_wire(link_id=0, clock=near)), 100.0) is SignatureCheck.VALID
    # 16 more link ids push link 0 out: its old frame is "not seen since boot" again, so the too-old check applies
    for link_id in range(1, LINK_IDS_HELD + 1):
        assert verifier.check(_inner(_signed_wire(link_id=link_id, clock=near, seq=link_id)), 100.0) is (
            SignatureCheck.VALID)
    old = Clock(T0_NS - int((NEW_LINK_WINDOW_S + 5) * 1e9))
    assert verifier.check(_inner(_signed_wire(link_id=0, clock=old)), 100.0) is SignatureCheck.TOO_OLD


def test_the_persisted_mark_refuses_what_was_accepted_before_a_reboot() -> None:
    marks: list[int] = []
    before = SignatureVerifier(KEY, persist=marks.append)
    first = _inner(_signed_wire(link_id=1))
    assert before.check(first, 0.0) is SignatureCheck.VALID
    stamp = timestamp_from_unix_ns(T0_NS)
    assert marks == [stamp + int(MARK_AHEAD_S * 100_000)]
    # within the mark: no second write (at most one write per 10 s)
    assert before.check(_inner(_signed_wire(link_id=1, clock=Clock(T0_NS + 10**9))), 1.0) is SignatureCheck.VALID
    assert len(marks) == 1
    after = SignatureVerifier(KEY, floor=marks[-1])  # rebooted: RAM state gone, the mark read back
    assert after.check(first, 0.0) is SignatureCheck.REPLAYED
    later = Clock(T0_NS + int((MARK_AHEAD_S + 1) * 1e9))
    assert after.check(_inner(_signed_wire(link_id=7, clock=later)), 0.0) is SignatureCheck.VALID


def test_authenticate_changes_no_state_and_admit_does() -> None:
    verifier = SignatureVerifier(KEY)
    inner = _inner(_signed_wire())
    assert verifier.authenticate(inner) is SignatureCheck.VALID
    assert verifier.authenticate(inner) is SignatureCheck.VALID
    assert verifier.admit(inner, 0.0) is SignatureCheck.VALID
    assert verifier.admit(inner, 0.0) is SignatureCheck.REPLAYED


def test_stripping_the_signed_flag_leaves_an_unsigned_frame_not_a_valid_one() -> None:
    body = bytearray(_inner(_signed_wire())[:-2])
    body[1] &= ~FrameFlag.SIGNED
    assert SignatureVerifier(KEY).check(_with_crc(bytes(body)), 0.0) is SignatureCheck.UNSIGNED


def test_the_same_bytes_again_are_a_replay() -> None:
    verifier = SignatureVerifier(KEY)
    inner = _inner(_signed_wire())
    assert verifier.check(inner, 0.0) is SignatureCheck.VALID
    assert verifier.check(inner, 0.5) is SignatureCheck.REPLAYED
    assert verifier.stats.replayed == 1


def test_an_older_timestamp_on_the_same_link_is_a_replay_and_a_newer_one_passes() -> None:
    clock = Clock()
    signer = Signer(KEY, 3, clock_ns=clock)
    encoder = FrameEncoder(signer=signer)
    first = _inner(encoder.encode(Stop()).wire)
    second = _inner(encoder.encode(Stop()).wire)
    verifier = SignatureVerifier(KEY)
    assert verifier.check(second, 0.0) is SignatureCheck.VALID
    assert verifier.check(first, 0.0) is SignatureCheck.REPLAYED
    clock.ns += 10**9
    assert verifier.check(_inner(encoder.encode(Stop()).wire), 1.0) is SignatureCheck.VALID


def test_a_new_link_far_behind_the_estimate_is_too_old_but_one_within_the_window_passes() -> None:
    verifier = SignatureVerifier(KEY)
    assert verifier.check(_inner(_signed_wire(link_id=1)), 100.0) is SignatureCheck.VALID
    old_ns = T0_NS - int((NEW_LINK_WINDOW_S + 5) * 1e9)
    assert verifier.check(_inner(_signed_wire(link_id=2, clock=Clock(old_ns))), 100.0) is SignatureCheck.TOO_OLD
    recent_ns = T0_NS - int((NEW_LINK_WINDOW_S - 5) * 1e9)
    assert verifier.check(_inner(_signed_wire(link_id=3, clock=Clock(recent_ns))), 100.0) is SignatureCheck.VALID
    # the receiver's own clock moves the estimate on: a minute later the same kind of stamp is too old
    late = _inner(_signed_wire(link_id=4, clock=Clock(recent_ns)))
    assert verifier.check(late, 100.0 + 10.0) is SignatureCheck.TOO_OLD


def test_the_signer_never_repeats_a_timestamp_even_when_the_clock_stands_still_or_steps_back() -> None:
    clock = Clock()
    signer = Signer(KEY, 1, clock_ns=clock)
    stamps = [signer.next_timestamp() for _ in range(3)]
    clock.ns -= 10**10
    stamps.append(signer.next_timestamp())
    assert stamps == sorted(set(stamps)) and stamps[0] == timestamp_from_unix_ns(T0_NS)


def test_a_retry_keeps_seq_and_payload_and_is_signed_afresh() -> None:
    encoder = FrameEncoder(40, signer=Signer(KEY, 9, clock_ns=Clock()))
    sent = encoder.encode(SetTarget(target_depth_m=0.75))
    again = encoder.retry(sent.wire)
    decoder, verifier = StreamDecoder(), SignatureVerifier(KEY)
    first, second = decoder.feed(sent.wire + again)
    assert (first.seq, first.message) == (second.seq, second.message) == (40, SetTarget(target_depth_m=0.75))
    assert [verifier.check(f.inner, 0.0) for f in (first, second)] == [SignatureCheck.VALID] * 2
    assert FrameEncoder().retry(sent.wire) == sent.wire  # without a signer a retry is the same bytes


def test_telemetry_stays_readable_unsigned_and_is_reported_unsigned() -> None:
    wire = FrameEncoder().encode(Sample(sample=5, depth_m=0.5)).wire
    frame = StreamDecoder().feed(wire)[0]
    assert frame.message.sample == 5 and not frame.signed  # type: ignore[attr-defined]
    assert SignatureVerifier(KEY).check(frame.inner, 0.0) is SignatureCheck.UNSIGNED


def test_a_signed_payload_has_13_bytes_less_room() -> None:
    encoder = FrameEncoder(signer=Signer(KEY, 1))
    encoder.encode_payload(0x05, bytes(234))
    with pytest.raises(FrameError):
        encoder.encode_payload(0x05, bytes(235))


def test_key_text_round_trips_and_bad_keys_are_refused() -> None:
    assert parse_key(format_key(KEY)) == KEY
    assert parse_key("  " + KEY.hex().upper() + "\n") == KEY
    for bad in ("", "zz" * 32, KEY.hex()[:-2]):
        with pytest.raises(SigningError):
            parse_key(bad)
    with pytest.raises(SigningError):
        Signer(KEY, 256)
