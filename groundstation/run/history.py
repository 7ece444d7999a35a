"""What a tool attaching to the hub late is given first: the run's episode table, its last dumps and the last
minutes of telemetry (bounded in time and bytes), so a learning curve and the heatmaps are whole from the start.

A session listener kept by the run; the hub answers a tool's LOG_REQUEST from it (the agent's own log is not
asked again over its one link). Frames are kept as their payloads and replayed with the REPLAYED flag, so the tool
files them as backfill beside the live frames that reach it from its HELLO on (`dive view` asks at once).
"""

from __future__ import annotations

import threading
from collections import deque
from dataclasses import dataclass

from groundstation.session.events import LinkEvent, Received, Sent
from protocol import messages as m

_TELEMETRY = (m.Sample.MSG_ID, m.EpisodeStart.MSG_ID, m.EpisodeEnd.MSG_ID, m.Text.MSG_ID)
_EPISODES = (m.EpisodeStart.MSG_ID, m.EpisodeEnd.MSG_ID)
FRAME_OVERHEAD = 8  # header, CRC and COBS bytes per frame, about


@dataclass(frozen=True, slots=True)
class HistoryConfig:
    window_s: float = 120.0  # telemetry of the last this many seconds (host time)
    max_bytes: int = 2 * 1024 * 1024  # and at most this much of it (under the hub's 4 MiB per client)
    max_episode_frames: int = 20_000  # EPISODE_START / END frames kept from before the window


@dataclass(frozen=True, slots=True)
class Kept:
    host_time_ns: int
    msg_id: int
    payload: bytes
    sample: int | None  # the SAMPLE index, for a LOG_REQUEST's range


class History:
    """The run's recent frames; on_received runs on the session's reader thread, replay() on the hub's."""

    def __init__(self, config: HistoryConfig | None = None) -> None:
        self.config = config or HistoryConfig()
        self._lock = threading.Lock()
        self._window: deque[Kept] = deque()
        self._window_bytes = 0
        self._episodes: deque[Kept] = deque(maxlen=self.config.max_episode_frames)
        self._dumps: dict[int, tuple[int, list[Kept]]] = {}  # kind -> (dump_id, its chunks), the newest dump

    def on_received(self, received: Received) -> None:
        if received.after_end:
            return
        frame = received.frame
        msg_id = frame.msg_id
        if msg_id == m.DumpChunk.MSG_ID:
            self._keep_dump(received)
            return
        if msg_id not in _TELEMETRY:
            return  # HEARTBEAT above all: a tool's idea of the agent's mode must be live
        message = frame.message
        kept = Kept(received.host_time_ns, msg_id, bytes(frame.payload), getattr(message, "sample", None))
        with self._lock:
            if msg_id in _EPISODES:
                self._episodes.append(kept)
            self._window.append(kept)
            self._window_bytes += len(kept.payload) + FRAME_OVERHEAD
            self._trim(received.host_time_ns)

    def _keep_dump(self, received: Received) -> None:
        chunk = received.message
        assert isinstance(chunk, m.DumpChunk)
        kept = Kept(received.host_time_ns, m.DumpChunk.MSG_ID, bytes(received.frame.payload), None)
        with self._lock:
            dump_id, chunks = self._dumps.get(chunk.kind, (chunk.dump_id, []))
            if dump_id != chunk.dump_id:
                chunks = []  # a newer dump of this kind replaces the older one
            chunks.append(kept)
            self._dumps[chunk.kind] = (chunk.dump_id, chunks)

    def _trim(self, now_ns: int) -> None:
        oldest_ns = now_ns - int(self.config.window_s * 1e9)
        window = self._window
        while window and (window[0].host_time_ns < oldest_ns or self._window_bytes > self.config.max_bytes):
            dropped = window.popleft()
            self._window_bytes -= len(dropped.payload) + FRAME_OVERHEAD

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass

    def replay(self, first_sample: int = 0, end_sample: int = 0xFFFFFFFF) -> list[tuple[int, bytes]]:
        """(msg_id, payload) in the order a tool wants them: the episodes from before the window, the last dumps,
        then the window; SAMPLE and episode frames outside [first_sample, end_sample) left out."""
        with self._lock:
            window = list(self._window)
            episodes = list(self._episodes)
            dumps = [chunk for _, chunks in self._dumps.values() for chunk in chunks]
        start_ns = window[0].host_time_ns if window else None
        before = [k for k in episodes if start_ns is None or k.host_time_ns < start_ns]

        def wanted(k: Kept) -> bool:
            return k.sample is None or first_sample <= k.sample < end_sample

        return [(k.msg_id, k.payload) for k in (*before, *dumps, *window) if wanted(k)]

    def log_range(self, replayed: int) -> m.LogRange:
        """The LOG_RANGE that ends a replay: the samples the window holds."""
        with self._lock:
            samples = [k.sample for k in self._window if k.msg_id == m.Sample.MSG_ID and k.sample is not None]
            used = self._window_bytes
        first, after = (samples[0], samples[-1] + 1) if samples else (0, 0)
        return m.LogRange(first_sample=first, next_sample=after, replayed=replayed, bytes_used=used,
                          capacity_bytes=self.config.max_bytes)
