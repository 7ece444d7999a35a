"""In-memory link pair for unit tests: two ends of a queue-backed byte pipe."""

from __future__ import annotations

import queue

from groundstation.errors import LinkError
from groundstation.links import Link


class MemoryLink(Link):
    """One end of a pipe; `peer` is the other end (for a fake agent). A closed peer raises LinkError."""

    def __init__(self, url: str = "memory://") -> None:
        super().__init__(url)
        self._inbox: queue.Queue[bytes | None] = queue.Queue()
        self.peer: MemoryLink | None = None
        self._connected = False

    @classmethod
    def pair(cls) -> tuple[MemoryLink, MemoryLink]:
        a, b = cls("memory://ground"), cls("memory://agent")
        a.peer, b.peer = b, a
        return a, b

    def _connect(self) -> None:
        if self.peer is None:
            raise LinkError(f"{self.url}: no peer")
        self._connected = True

    def _disconnect(self) -> None:
        if self._connected and self.peer is not None:
            self.peer._inbox.put(None)  # the other end sees end of stream
        self._connected = False

    def _read(self, timeout_s: float) -> bytes:
        try:
            data = self._inbox.get(timeout=timeout_s) if timeout_s > 0 else self._inbox.get_nowait()
        except queue.Empty:
            return b""
        if data is None:
            raise LinkError(f"{self.url}: peer closed")
        return data

    def _write(self, data: bytes) -> None:
        if self.peer is None or not self._connected:
            raise LinkError(f"{self.url}: not connected")
        self.peer._inbox.put(bytes(data))
