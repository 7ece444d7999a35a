"""Junk on the wire: each kind of bad chunk is dropped and counted once, in HEARTBEAT's rx_rejects (SPEC.md 1)."""

from __future__ import annotations

from collections.abc import Callable

from groundstation.check.probe import Probe
from groundstation.check.registry import check, expect
from protocol import FrameFlag
from protocol import messages as m
from protocol.cobs import cobs_encode
from protocol.crc import crc16_ccitt_false

RECEIVE = "1 Frame: receiving"
COUNTERS = "4 Link life cycle: counters"
_SENTENCE_REJECTS = """rx_rejects: every chunk dropped without being acted on: oversize, COBS error, runt, CRC error,
    incompatible, unknown id below 0x80, malformed (SIGNED set on a non-command frame too short for a trailer). Each
    such chunk counts exactly once."""


def _wire(inner: bytes) -> bytes:
    return cobs_encode(inner) + b"\x00"


def _with_crc(body: bytes) -> bytes:
    return body + crc16_ccitt_false(body).to_bytes(2, "big")


def _header(probe: Probe, msg_id: int, flags: int = 0, *, take_seq: bool) -> bytes:
    """ver | flags | seq | msg_id with the probe's next seq: taken when the agent counts the frame's seq."""
    seq = probe.next_seq() if take_seq else probe.upcoming_seq
    return bytes([1, flags]) + seq.to_bytes(2, "little") + bytes([msg_id])


def counted_once(probe: Probe, junk: Callable[[], bytes], what: str, rejects: int = 1) -> str:
    """Send `junk` between two counter readings: rx_rejects grows by `rejects`, nothing else moves, no ACK."""
    before = probe.counters()
    sent_before = probe.sent_valid
    start = probe.end
    probe.send_raw(junk())
    after = probe.counters()
    valid = probe.sent_valid - sent_before
    deltas = {name: (getattr(after, name) - getattr(before, name)) & 0xFFFFFFFF
              for name in ("rx_rejects", "rx_frames", "rx_lost", "signing_rejects")}
    wanted = {"rx_rejects": rejects, "rx_frames": valid, "rx_lost": 0, "signing_rejects": 0}
    wrong = [f"{k} +{v} (wanted +{wanted[k]})" for k, v in deltas.items() if v != wanted[k]]
    expect(not wrong, f"{what}: " + ", ".join(wrong))
    acks = probe.messages(m.Ack, start)
    expect(not acks, f"{what} was answered with an ACK (cmd_msg_id 0x{acks[0].cmd_msg_id:02X})" if acks else "")
    return f"{what}: rx_rejects +{rejects}, other counters unchanged"


@check("junk.oversize", RECEIVE, """A chunk longer than 255 bytes is oversize: discard it as it grows (keep dropping
       bytes until the next 0x00), so the buffer never holds more than 255 bytes; count it once. """
       + _SENTENCE_REJECTS)
def oversize(probe: Probe) -> str:
    return counted_once(probe, lambda: b"\x00" + b"\x11" * 300 + b"\x00", "a 300-byte chunk")


@check("junk.oversize_256", RECEIVE, """A chunk longer than 255 bytes is oversize. A 254-byte inner frame encodes
       to at most 255 bytes.""")
def oversize_256(probe: Probe) -> str:
    def chunk() -> bytes:
        # A TEXT frame of 255 inner bytes (one more than allowed) with a valid CRC: 256 bytes of COBS.
        text = bytes(8) + b"\x01" + b"a" * 239  # TEXT t_us | severity | text: a 248-byte payload
        wire = _wire(_with_crc(_header(probe, m.Text.MSG_ID, take_seq=False) + text))
        assert len(wire) == 257, len(wire)
        return wire
    return counted_once(probe, chunk, "a 256-byte chunk holding a 255-byte frame with a valid CRC")


@check("junk.cobs_error", RECEIVE, """COBS-decode (a code byte pointing past the end of the chunk is a COBS
       error). """ + _SENTENCE_REJECTS)
def cobs_error(probe: Probe) -> str:
    return counted_once(probe, lambda: b"\x09\x01\x02\x03\x00", "a code byte pointing past the chunk's end")


@check("junk.runt", RECEIVE, "check length ≥ 7 (else runt). " + _SENTENCE_REJECTS)
def runt(probe: Probe) -> str:
    return counted_once(probe, lambda: _wire(b"\x01\x00\x05\x00\x03\x01"), "a 6-byte frame")


@check("junk.crc_error", RECEIVE, "the CRC (CRC error). " + _SENTENCE_REJECTS)
def crc_error(probe: Probe) -> str:
    def chunk() -> bytes:
        inner = bytearray(_with_crc(_header(probe, m.Timesync.MSG_ID, take_seq=False) + bytes(24)))
        inner[-1] ^= 0x5A
        return _wire(bytes(inner))
    return counted_once(probe, chunk, "a TIMESYNC with a wrong CRC")


@check("junk.version", RECEIVE, "ver = 1 [...] (incompatible). " + _SENTENCE_REJECTS)
def version(probe: Probe) -> str:
    def chunk() -> bytes:
        body = bytearray(_header(probe, m.Timesync.MSG_ID, take_seq=False) + bytes(24))
        body[0] = 2
        return _wire(_with_crc(bytes(body)))
    return counted_once(probe, chunk, "a version-2 frame")


@check("junk.incompatible_flag", RECEIVE, """ver = 1 and no unknown incompatible flag, i.e. flags & 0xE0 = 0
       (incompatible). """ + _SENTENCE_REJECTS)
def incompatible_flag(probe: Probe) -> str:
    return counted_once(probe, lambda: _wire(_with_crc(_header(probe, m.Timesync.MSG_ID, 0x80, take_seq=False)
                                                       + bytes(24))), "a frame with flag bit 7 set")


@check("junk.unknown_id", RECEIVE, """sequence tracking counts the frame, whatever its msg_id; look up msg_id. An
       unknown id below 0x80 is dropped (unknown id).""")
def unknown_id(probe: Probe) -> str:
    return counted_once(probe, lambda: _wire(_with_crc(_header(probe, 0x30, take_seq=True))),
                        "a frame with unknown id 0x30")


@check("junk.malformed_signed", RECEIVE, """if SIGNED is set: an inner frame shorter than 7 + 13 = 20 bytes has no
       room for its trailer. [...] any other frame [than a command] is dropped (malformed).""")
def malformed_signed(probe: Probe) -> str:
    signed = int(FrameFlag.SIGNED)
    return counted_once(probe, lambda: _wire(_with_crc(_header(probe, m.Timesync.MSG_ID, signed, take_seq=True)
                                                       + bytes(4))), "a SIGNED TIMESYNC too short for a trailer")


@check("junk.empty_chunk", RECEIVE, """An empty chunk is ignored and counted nowhere, so a sender may start with
       0x00 to flush line noise.""")
def empty_chunk(probe: Probe) -> str:
    return counted_once(probe, lambda: b"\x00\x00\x00", "three 0x00 bytes", rejects=0)


@check("counters.rx_frames", COUNTERS, """rx_frames: frames that passed the CRC and version checks and were handed
       to the program. A frame is counted in rx_frames or in rx_rejects, never both.""")
def rx_frames(probe: Probe) -> str:
    before = probe.counters()
    sent = probe.sent_valid
    for i in range(5):
        probe.send(m.Timesync(origin_us=10 + i, receive_us=20, transmit_us=30))  # replies: nothing answers them
    after = probe.counters()
    grew = (after.rx_frames - before.rx_frames) & 0xFFFFFFFF
    wanted = probe.sent_valid - sent
    expect(grew == wanted, f"{wanted} valid frames sent, rx_frames grew by {grew}")
    return f"{wanted} frames sent, rx_frames +{grew}"
