"""A listener that takes the session's traffic to a thread of its own: a viewer never holds up the reader thread.

The session calls its listeners on its reader thread, the one that also feeds the recorder and answers the agent.
A viewer (Foxglove, Rerun) can be slow for reasons of its own (a client subscribing, a replay, the GIL), and it
must not make the recording lose a sample (issue 38 N3). So the session only appends to a bounded queue here;
the viewer's listener is called from this thread. When the queue is full the newest item is dropped and counted:
the recording never waits for a viewer.
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable

from groundstation.session.events import LinkEvent, Received, Sent, SessionListener

_Call = tuple[Callable[[object], None], object]


class Handoff:
    """on_received / on_sent / on_event of `listener`, called from a thread of this object's, in order."""

    def __init__(self, listener: SessionListener, capacity: int, name: str) -> None:
        self.listener = listener
        self.capacity = capacity
        self.dropped = 0  # items the queue had no room for
        self.failure: str | None = None  # what the listener raised, once: it is called no more
        self._queue: deque[_Call] = deque()
        self._ready = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._deliver, name=name, daemon=True)
        self._thread.start()

    def _put(self, call: _Call) -> None:
        with self._ready:
            if len(self._queue) >= self.capacity:
                self.dropped += 1
                return
            self._queue.append(call)
            if len(self._queue) == 1:
                self._ready.notify()

    def on_received(self, received: Received) -> None:
        self._put((self.listener.on_received, received))  # type: ignore[arg-type]

    def on_sent(self, sent: Sent) -> None:
        self._put((self.listener.on_sent, sent))  # type: ignore[arg-type]

    def on_event(self, event: LinkEvent) -> None:
        self._put((self.listener.on_event, event))  # type: ignore[arg-type]

    @property
    def waiting(self) -> int:
        with self._ready:
            return len(self._queue)

    def _deliver(self) -> None:
        while True:
            with self._ready:
                while not self._queue and not self._closed:
                    self._ready.wait()
                if not self._queue:
                    return  # closed, everything delivered
                batch = list(self._queue)
                self._queue.clear()
            for method, item in batch:
                if self.failure is not None:
                    break
                try:
                    method(item)
                except Exception as e:  # noqa: BLE001 a viewer's bug: it stops, the session and recording go on
                    self.failure = f"{type(e).__name__}: {e}"

    def close(self, timeout_s: float = 2.0) -> None:
        """Deliver what is queued (for up to timeout_s), then end the thread."""
        with self._ready:
            self._closed = True
            self._ready.notify()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout_s)
