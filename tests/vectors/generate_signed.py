"""Writes tests/vectors/signed.jsonl, the golden signed frames: `python -m tests.vectors.generate_signed`.

Each line: `key_hex`, `link_id`, `timestamp` (10 µs units since 2015-01-01 UTC), `name`, `fields`, `flags`,
`seq`, `signed_part_hex` (the bytes the HMAC runs over), `signature_hex`, `inner_hex` and `wire_hex`.
SPEC.md section 12 walks through the first line byte by byte.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from protocol import FrameEncoder, messages
from protocol.cobs import cobs_decode
from protocol.registry import Message
from protocol.signing import EPOCH_2015_UNIX_S, RESYNC_NAME, TIMESTAMP_UNIT_US, Signer

SIGNED_VECTORS_PATH = Path(__file__).with_name("signed.jsonl")
KEY = bytes(range(32))  # 00 01 02 ... 1f: a test key, never a real one
T_2025_S = 1_735_689_600  # 2025-01-01 00:00:00 UTC
TIMESTAMP = (T_2025_S - EPOCH_2015_UNIX_S) * 1_000_000 // TIMESTAMP_UNIT_US

# (message, link id, seq, timestamp)
CASES: list[tuple[Message, int, int, int]] = [
    (messages.SetTarget(target_depth_m=1.5), 1, 18, TIMESTAMP),
    (messages.Surface(), 1, 19, TIMESTAMP + 1),
    (messages.Text(t_us=1, severity=1, text="signed text[] tail"), 200, 65535, TIMESTAMP + 100_000),
    (messages.Heartbeat(uptime_ms=1000), 200, 0, 2**48 - 1),
    # the re-sync of SPEC.md s. 12 with the nonce 0x0a1b2c3d: a PARAM_SET, not a parameter
    (messages.ParamSet(index=-1, value=float(0x0A1B2C3D), name=RESYNC_NAME), 1, 20, TIMESTAMP + 2),
]


def vector(message: Message, link_id: int, seq: int, timestamp: int) -> dict[str, Any]:
    """One golden signed frame; the signer's clock is pinned so that it stamps exactly `timestamp`."""
    unix_ns = (EPOCH_2015_UNIX_S * 1_000_000 + timestamp * TIMESTAMP_UNIT_US) * 1000
    encoded = FrameEncoder(first_seq=seq, signer=Signer(KEY, link_id, clock_ns=lambda: unix_ns)).encode(message)
    inner = cobs_decode(encoded.wire[:-1])
    return {
        "key_hex": KEY.hex(),
        "link_id": link_id,
        "timestamp": timestamp,
        "name": message.DEFINITION.name,
        "fields": message.to_dict(),
        "flags": inner[1],
        "seq": encoded.seq,
        "signed_part_hex": inner[:-8].hex(),
        "signature_hex": inner[-8:-2].hex(),
        "inner_hex": inner.hex(),
        "wire_hex": encoded.wire.hex(),
    }


def render() -> str:
    return "".join(json.dumps(vector(*case), ensure_ascii=False) + "\n" for case in CASES)


def main() -> None:
    SIGNED_VECTORS_PATH.write_text(render(), encoding="utf-8")
    print(f"wrote {len(CASES)} signed vectors to {SIGNED_VECTORS_PATH}")


if __name__ == "__main__":
    main()
