"""Link fault injection on both directions: frame drops, byte corruption, delay, forced disconnects, blackout."""

from __future__ import annotations

import heapq
import random
from dataclasses import dataclass

from protocol.cobs import cobs_decode
from protocol.errors import CobsError
from simulator.errors import ParamsError

MAX_LOGGED_SEQS = 1_000_000  # seqs kept for the --report file; plenty for a test, a soak only needs the counts


def frame_seq(wire: bytes) -> int | None:
    """The seq of an encoded frame (COBS + 0x00), or None if it is not a decodable frame."""
    try:
        inner = cobs_decode(wire.rstrip(b"\x00"))
    except CobsError:
        return None
    return inner[2] | inner[3] << 8 if len(inner) >= 4 else None


@dataclass(frozen=True)
class FaultConfig:
    """What `serve --drop/--corrupt/--delay/--disconnect-every/--blackout-below` ask for.

    - drop_p: probability that a whole frame is lost (each direction, each frame).
    - corrupt_p: probability that one byte of a frame is replaced by another value.
    - delay_ms: wall-clock latency added to every byte, each direction (a network delay, so wall time).
    - disconnect_every_s: the agent closes the connection every this many seconds of AGENT time
      (0 = never). Agent time, so an outage pattern is the same at every --speed and lines up with
      the dive; at --speed max choose a correspondingly larger value. A connection is never closed before it
      has lasted `min_connection_s` of wall time (1 s + 4 delays): at --speed 100, 20 s of agent time is 0.2 s
      of wall time, shorter than one round trip with a 200 ms delay, and no command could ever be answered.
    - blackout_below_m: the radio works only shallower than this true depth (None = always): deeper,
      frames are neither sent nor received (lost, not queued), as Wi-Fi does not reach through water.
    """

    drop_p: float = 0.0
    corrupt_p: float = 0.0
    delay_ms: float = 0.0
    disconnect_every_s: float = 0.0
    blackout_below_m: float | None = None

    def __post_init__(self) -> None:
        for name in ("drop_p", "corrupt_p"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ParamsError(f"--{name[:-2]} must lie in [0, 1], got {value}")
        if self.delay_ms < 0 or self.disconnect_every_s < 0:
            raise ParamsError("--delay and --disconnect-every must not be negative")
        if self.blackout_below_m is not None and self.blackout_below_m < 0:
            raise ParamsError("--blackout-below must not be negative")

    @property
    def min_connection_s(self) -> float:
        """Wall time a connection lasts at least before a forced disconnect: two round trips and a second."""
        return 1.0 + 4 * self.delay_ms / 1000.0

    @property
    def active(self) -> bool:
        return bool(self.drop_p or self.corrupt_p)


class FrameFaults:
    """Drops and corrupts whole frames of one direction; incoming bytes are cut into frames at 0x00 first."""

    def __init__(self, config: FaultConfig, rng: random.Random) -> None:
        self._drop_p = config.drop_p
        self._corrupt_p = config.corrupt_p
        self._rng = rng
        self._partial = b""
        self.dropped = 0
        self.corrupted = 0

    def frame(self, wire: bytes) -> bytes:
        """One encoded frame (ending in 0x00) as it leaves the faulty link; b"" if it is lost."""
        rng = self._rng
        if self._drop_p and rng.random() < self._drop_p:
            self.dropped += 1
            return b""
        if self._corrupt_p and len(wire) > 1 and rng.random() < self._corrupt_p:
            self.corrupted += 1
            position = rng.randrange(len(wire) - 1)  # never the delimiter: frames keep their boundaries
            buffer = bytearray(wire)
            buffer[position] = (buffer[position] + rng.randrange(1, 256)) & 0xFF
            return bytes(buffer)
        return wire

    def stream(self, data: bytes) -> bytes:
        """Arbitrary received bytes: complete frames pass through frame(), a trailing partial one waits."""
        if not self._drop_p and not self._corrupt_p:
            return data
        data = self._partial + data
        end = data.rfind(0)
        self._partial = data[end + 1 :]
        if end < 0:
            return b""
        return b"".join(self.frame(chunk + b"\x00") for chunk in data[:end].split(b"\x00"))

    def reset(self) -> None:
        """A new connection: forget a partial frame of the old one."""
        self._partial = b""


class DelayLine:
    """Holds byte strings until their release time (wall clock, s); order is kept."""

    def __init__(self, delay_s: float) -> None:
        self.delay_s = delay_s
        self._queue: list[tuple[float, int, bytes]] = []
        self._counter = 0

    def __len__(self) -> int:
        return len(self._queue)

    def put(self, now_s: float, data: bytes) -> None:
        self._counter += 1
        heapq.heappush(self._queue, (now_s + self.delay_s, self._counter, data))

    def due(self, now_s: float) -> bytes:
        """Everything whose release time has come, concatenated."""
        out: list[bytes] = []
        queue = self._queue
        while queue and queue[0][0] <= now_s:
            out.append(heapq.heappop(queue)[2])
        return b"".join(out)

    def next_release_s(self) -> float | None:
        return self._queue[0][0] if self._queue else None

    def clear(self) -> None:
        self._queue.clear()
