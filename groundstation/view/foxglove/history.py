"""What a Foxglove client that subscribes late is sent first, on its channel only: the episodes, the last dumps and
the last minutes of telemetry (bounded in time and count), as run/history.py gives a tool attaching to the hub."""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

# Topics kept whole (up to max_whole): the learning curve and the alarms must be whole from the first episode.
WHOLE = frozenset({"/agent/EPISODE_START", "/agent/EPISODE_END", "/event", "/marker"})
LAST_ONLY_PREFIX = "/dump/"  # a dump replaces the one before it: only the newest is worth sending


@dataclass(frozen=True, slots=True)
class FoxgloveHistoryConfig:
    window_s: float = 120.0  # telemetry of the last this many seconds (host time), as run/history.py keeps
    max_per_topic: int = 10_000  # and at most this many messages of a topic (at --speed max seconds are many)
    max_whole: int = 20_000  # messages kept of each WHOLE topic


# The server's queue per client (the SDK's default is 1024, whose oldest messages it drops when full): a late
# client's replays of the SAMPLEs and the episodes must fit in it, or their oldest part would be lost.
CLIENT_BACKLOG = 65_536


Body = Callable[[], bytes]  # a message's JSON, encoded only when a client asks for it


class Kept:
    """One kept message: its time and its body, encoded at most once (a client that subscribes again, or another
    client, is sent the same bytes: a flapping subscription costs sends, not JSON encoding, issue 38 N3)."""

    __slots__ = ("body", "host_time_ns")

    def __init__(self, host_time_ns: int, body: Body | bytes) -> None:
        self.host_time_ns = host_time_ns
        self.body = body

    def encoded(self) -> bytes:
        body = self.body
        if not isinstance(body, bytes):
            body = self.body = body()
        return body


class ChannelHistory:
    """Per topic, the recent messages as (time, body encoder): keep() runs on the publisher's thread for every
    frame, so it only appends; snapshot() is taken when a client subscribes and encoded outside every lock."""

    def __init__(self, config: FoxgloveHistoryConfig | None = None) -> None:
        self.config = config or FoxgloveHistoryConfig()
        self._lock = threading.Lock()
        self._topics: dict[str, deque[Kept]] = {}
        self._window_ns = int(self.config.window_s * 1e9)

    def keep(self, topic: str, host_time_ns: int, body: Body | bytes) -> None:
        with self._lock:
            kept = self._topics.get(topic)
            if kept is None:
                kept = self._topics[topic] = deque(maxlen=self._bound(topic))
            kept.append(Kept(host_time_ns, body))
            if topic not in WHOLE:
                oldest_ns = host_time_ns - self._window_ns
                while kept and kept[0].host_time_ns < oldest_ns:
                    kept.popleft()

    def keep_bytes(self, topic: str, host_time_ns: int, body: bytes) -> None:
        self.keep(topic, host_time_ns, body)

    def _bound(self, topic: str) -> int:
        if topic.startswith(LAST_ONLY_PREFIX):
            return 1
        return self.config.max_whole if topic in WHOLE else self.config.max_per_topic

    def snapshot(self, topic: str) -> list[Kept]:
        """`topic`'s kept messages, oldest first, not yet encoded (a copy of the list: cheap under the lock)."""
        with self._lock:
            return list(self._topics.get(topic, ()))

    def replay(self, topic: str) -> list[tuple[int, bytes]]:
        """(host time ns, JSON body) of `topic`'s kept messages, oldest first."""
        return [(kept.host_time_ns, kept.encoded()) for kept in self.snapshot(topic)]
