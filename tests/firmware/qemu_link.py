"""The emulated agent's link as a test reads it: decoded frames off its TCP socket for a while."""

from __future__ import annotations

import socket
import time

from protocol import StreamDecoder


def read_frames(address: str, seconds: float, until: type | None = None) -> list[object]:
    """What the agent sends within `seconds` (or until a message of type `until`); the stream must decode clean."""
    host, port = address.removeprefix("tcp://").rsplit(":", 1)
    decoder = StreamDecoder()
    found: list[object] = []
    with socket.create_connection((host, int(port)), timeout=2.0) as s:
        s.settimeout(0.2)
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                data = s.recv(4096)
            except TimeoutError:
                continue
            found += [f.message for f in decoder.feed(data)]
            if until is not None and any(isinstance(m, until) for m in found):
                break
    assert decoder.stats.crc_errors == 0 and decoder.stats.cobs_errors == 0
    return found
