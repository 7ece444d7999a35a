"""Writes tests/vectors/receive.jsonl, what an agent does with given bytes: `python -m tests.vectors.generate_receive`.

Each line: `name`, `wire_hex` (bytes as they arrive, possibly several frames), and what an agent without a key must
do with them (SPEC.md sections 1, 4 and 5): `rx_frames`, `rx_rejects`, `rx_lost` (the HEARTBEAT counters they
add), `cause` (the reject cause, or null) and `ack` (the ACK result name each command frame gets, in order).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from protocol import FrameEncoder, FrameFlag, messages
from protocol.cobs import cobs_encode
from protocol.crc import crc16_ccitt_false
from protocol.signing import Signer

RECEIVE_VECTORS_PATH = Path(__file__).with_name("receive.jsonl")
KEY = bytes(range(32))
ACK = int(FrameFlag.ACK_REQUESTED)
SIGNED = int(FrameFlag.SIGNED)


def _wire(body: bytes) -> bytes:
    """COBS(body + its CRC) and the delimiter: a frame with any header a test needs."""
    return cobs_encode(body + crc16_ccitt_false(body).to_bytes(2, "big")) + b"\x00"


def _signed_1_0(body: bytes) -> bytes:
    """A command signed as SPEC 1.0 did: flag bit 2 and a 13-byte trailer (any bytes: the HMAC is not read)."""
    return _wire(bytes([body[0], body[1] | 0x04]) + body[2:] + bytes(range(1, 14)))


def _case(name: str, wire: bytes, frames: int, rejects: int, cause: str | None, ack: list[str],
          lost: int = 0) -> dict[str, Any]:
    return {"name": name, "wire_hex": wire.hex(), "rx_frames": frames, "rx_rejects": rejects, "rx_lost": lost,
            "cause": cause, "ack": ack}


def cases() -> list[dict[str, Any]]:
    longest = FrameEncoder(7).encode(messages.Text(t_us=1, severity=3, text="é" * 119)).wire  # 254-byte inner
    signed = FrameEncoder(30, signer=Signer(KEY, 1, clock_ns=lambda: 1_735_689_600 * 10**9)).encode(
        messages.Surface(), ACK).wire
    seq = FrameEncoder(5)
    return [
        _case("unknown command id 0x8C: one ACK UNSUPPORTED, counted as a frame",
              _wire(bytes([1, ACK, 9, 0, 0x8C])), 1, 0, None, ["UNSUPPORTED"]),
        _case("unknown command id 0xFF without ACK_REQUESTED: still one ACK",
              _wire(bytes([1, 0, 10, 0, 0xFF, 1, 2, 3])), 1, 0, None, ["UNSUPPORTED"]),
        _case("SIGNED command too short for a trailer: ACK UNAUTHORIZED (truncated), with or without a key",
              _wire(bytes([1, ACK | SIGNED, 11, 0, 0x84])), 1, 0, None, ["UNAUTHORIZED"]),
        _case("SIGNED command 12 bytes short of a trailer: ACK UNAUTHORIZED",
              _wire(bytes([1, ACK | SIGNED, 12, 0, 0x86, 1, 2, 3, 4])), 1, 0, None, ["UNAUTHORIZED"]),
        _case("SIGNED non-command too short for a trailer: malformed",
              _wire(bytes([1, SIGNED, 13, 0, 0x02, 1, 2, 3])), 0, 1, "malformed", []),
        _case("unknown id 0x30 (not a command): dropped", _wire(bytes([1, 0, 14, 0, 0x30])), 0, 1, "unknown_id", []),
        _case("incompatible flag bit 5: dropped", _wire(bytes([1, 0x20, 15, 0, 0x81])), 0, 1, "incompatible", []),
        _case("version 2: dropped", _wire(bytes([2, 0, 16, 0, 0x81])), 0, 1, "incompatible", []),
        _case("a SPEC 1.0 signed CMD_STOP (bit 2): bit 2 is ignored, the frame is an unsigned command",
              _signed_1_0(bytes([1, ACK, 17, 0, 0x81])), 1, 0, None, ["ACCEPTED"]),
        _case("a 1.1 signed CMD_SURFACE to an agent without a key: the trailer is cut off, executed",
              signed, 1, 0, None, ["ACCEPTED"]),
        _case("256-byte chunk: oversize", bytes([0x55]) * 256 + b"\x00", 0, 1, "oversize", []),
        _case("the longest frame (254-byte inner, 255-byte chunk): kept", longest, 1, 0, None, []),
        _case("COBS code byte past the end: COBS error", bytes([0x05, 1, 2]) + b"\x00", 0, 1, "cobs_errors", []),
        _case("6-byte inner frame: runt", cobs_encode(bytes([1, 0, 0, 0, 0x81, 0])) + b"\x00", 0, 1, "runts", []),
        _case("wrong CRC", cobs_encode(bytes([1, ACK, 18, 0, 0x81, 0, 0])) + b"\x00", 0, 1, "crc_errors", []),
        _case("empty chunks between delimiters: ignored, nothing counted", b"\x00\x00\x00", 0, 0, None, []),
        _case("a HELLO resets sequence tracking before it is counted: no loss across it",
              seq.encode(messages.Heartbeat()).wire + FrameEncoder(900).encode(messages.Hello()).wire
              + FrameEncoder(901).encode(messages.Heartbeat()).wire, 3, 0, None, []),
        _case("a gap of 3 frames: rx_lost 3",
              FrameEncoder(40).encode(messages.Heartbeat()).wire + FrameEncoder(44).encode(messages.Heartbeat()).wire,
              2, 0, None, [], lost=3),
    ]


def render() -> str:
    return "".join(json.dumps(case, ensure_ascii=False) + "\n" for case in cases())


def main() -> None:
    RECEIVE_VECTORS_PATH.write_text(render(), encoding="utf-8")
    print(f"wrote {len(cases())} receive vectors to {RECEIVE_VECTORS_PATH}")


if __name__ == "__main__":
    main()
