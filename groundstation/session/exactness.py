"""Recordings are exact (issue 13 item 5): a frame received twice is handled once, and a SAMPLE index the agent
cannot have reached is not taken as true (one such index would otherwise open a gap of billions of "missing"
samples, and a backfill of them)."""

from __future__ import annotations

from collections import deque

RECENT_FRAMES = 512  # a duplicate comes within a few frames of its original (a radio or bridge sending twice)
MAX_SAMPLE_RATE_HZ = 50.0  # the agent's fastest SAMPLE stream: a 0.02 s control period (recovery: 0.025 s)
SAMPLE_SLACK = 1024  # on top of the rate bound: samples built before the heartbeat was sent, clock jitter


class RecentFrames:
    """The last RECENT_FRAMES inner frames (header, payload, CRC) of this connection.

    Byte-equal means the same seq and the same content: the same frame again. A replay from the on-board log has a
    new seq and the REPLAYED flag, so it is never taken for a duplicate of the live frame.
    """

    def __init__(self, size: int = RECENT_FRAMES) -> None:
        self._size = size
        self._held: set[bytes] = set()
        self._order: deque[bytes] = deque()
        self.duplicates = 0

    def seen(self, inner: bytes) -> bool:
        """True if `inner` came before (and is counted); else remember it."""
        if inner in self._held:
            self.duplicates += 1
            return True
        self._held.add(inner)
        self._order.append(inner)
        if len(self._order) > self._size:
            self._held.discard(self._order.popleft())
        return False

    def clear(self) -> None:
        """A new connection: its frames start a new sequence."""
        self._held.clear()
        self._order.clear()


class SampleIndexCheck:
    """Whether a SAMPLE index can be true, given the agent's latest HEARTBEAT (log_next_sample at uptime_ms).

    Between that heartbeat and the sample the agent can have made at most MAX_SAMPLE_RATE_HZ samples a second of its
    own time (the sample's t_us), plus SAMPLE_SLACK. Before any heartbeat every index is believed.
    """

    def __init__(self) -> None:
        self._next_sample: int | None = None
        self._at_us = 0
        self.impossible = 0

    def heartbeat(self, log_next_sample: int, uptime_ms: int) -> None:
        self._next_sample, self._at_us = log_next_sample, uptime_ms * 1000

    def reset(self) -> None:
        """The agent rebooted: its indices start again."""
        self._next_sample = None
        self._at_us = 0

    def possible(self, sample: int, t_us: int) -> bool:
        if self._next_sample is None:
            return True
        elapsed_s = max(0.0, (t_us - self._at_us) / 1e6)
        if sample <= self._next_sample + SAMPLE_SLACK + MAX_SAMPLE_RATE_HZ * elapsed_s:
            return True
        self.impossible += 1
        return False
