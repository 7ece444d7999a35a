"""A listener that takes the session's traffic to a thread of its own: a viewer never holds up the reader thread.

The session calls its listeners on its reader thread, the one that also feeds the recorder and answers the agent.
A viewer (Foxglove, Rerun) can be slow for reasons of its own (a client subscribing, a replay, the GIL), and it
must not make the recording lose a sample (issue 38 N3). So the session only appends to a bounded queue here;
the viewer's listener is called from this thread. When the queue is full the newest item is dropped and counted:
the recording never waits for a viewer.

The run's hub gives each tool one of these too (run/hub_outbox.py), with its own answer to a full queue: a tool
counts frames by sequence number, so it is not handed a silent hole but dropped, with a reason (_full, the hooks).
"""

from __future__ import annotations

import threading
from collections import deque
from collections.abc import Callable
from typing import Any

from groundstation.session.events import LinkEvent, Received, Sent, SessionListener

# (method, item, weight); a subclass may queue entries of its own kind with method None (see _run)
_Call = tuple[Callable[[Any], None] | None, Any, int]


class Outbox:
    """Calls queued from any thread, made in order on a thread of this object's; bounded by `capacity`."""

    batch_limit: int | None = None  # items handed over between two _delivered() calls (None: all queued)

    def __init__(self, capacity: int, name: str) -> None:
        self.capacity = capacity
        self.dropped = 0  # items the queue had no room for
        self.failure: str | None = None  # what a call raised, once: nothing more is called
        self._queue: deque[_Call] = deque()
        self._queued = 0  # the queue's weight: items, a call of many frames counting each (call(weight=))
        self._ready = threading.Condition()
        self._closed = False
        self._thread = threading.Thread(target=self._deliver, name=name, daemon=True)
        self._thread.start()

    def call(self, method: Callable[[Any], None], item: object, weight: int = 1) -> None:
        """method(item) on this object's thread, after what is queued; it takes `weight` of the capacity."""
        self._put((method, item, weight))

    def _put(self, entry: _Call) -> None:
        """Queue an entry as it is: one the caller built once can go to many queues (8 bytes a queue)."""
        weight = entry[2]
        with self._ready:
            if self._closed:
                self.dropped += weight
                return
            if self._queued + weight > self.capacity:
                self._full(weight)
                return
            self._queue.append(entry)
            self._queued += weight
            if len(self._queue) == 1:
                self._ready.notify()

    def _full(self, weight: int) -> None:
        """No room for `weight` more (called holding the queue's lock): a viewer's newest items are dropped."""
        self.dropped += weight

    def _run(self, method: Callable[[Any], None] | None, item: object) -> None:
        """One queued entry, on this object's thread."""
        assert method is not None  # entries without a method are a subclass's, which says what they mean
        method(item)

    def _delivered(self) -> None:
        """After each batch handed to the listener, on this object's thread (a writer flushes here)."""

    def _ended(self) -> None:
        """The thread's last act, once closed and everything queued delivered (or the listener failed)."""

    @property
    def waiting(self) -> int:
        with self._ready:
            return self._queued

    @property
    def ended(self) -> bool:
        return not self._thread.is_alive()

    def _take(self) -> list[_Call] | None:
        """The next batch, waiting for one; None once closed with nothing left."""
        with self._ready:
            while not self._queue and not self._closed:
                self._ready.wait()
            if not self._queue:
                return None
            if self.batch_limit is None or len(self._queue) <= self.batch_limit:
                batch = list(self._queue)
                self._queue.clear()
                self._queued = 0
            else:
                batch = [self._queue.popleft() for _ in range(self.batch_limit)]
                self._queued -= sum(weight for _, _, weight in batch)
            return batch

    def _deliver(self) -> None:
        try:
            while self.failure is None:
                batch = self._take()
                if batch is None:
                    return  # closed, everything delivered
                for method, item, _ in batch:
                    try:
                        self._run(method, item)
                    except Exception as e:  # noqa: BLE001 a viewer's (a writer's) bug: it stops; the session goes on
                        self.failure = f"{type(e).__name__}: {e}"
                        break
                if self.failure is None:
                    self._delivered()
            self._stop_taking()  # the listener failed: what comes is dropped and counted, not kept
        finally:
            self._ended()

    def _stop_taking(self) -> None:
        """Take nothing more, and let go of what is queued (counted as dropped)."""
        with self._ready:
            self._closed = True
            self.dropped += self._queued
            self._queue.clear()
            self._queued = 0

    def close(self, timeout_s: float = 2.0) -> None:
        """Deliver what is queued (for up to timeout_s), then end the thread."""
        with self._ready:
            self._closed = True
            self._ready.notify()
        if self._thread is not threading.current_thread():
            self._thread.join(timeout_s)


class Handoff(Outbox):
    """on_received / on_sent / on_event of `listener`, called from a thread of this object's, in order."""

    def __init__(self, listener: SessionListener, capacity: int, name: str) -> None:
        self.listener = listener
        super().__init__(capacity, name)

    def on_received(self, received: Received) -> None:
        self.call(self.listener.on_received, received)

    def on_sent(self, sent: Sent) -> None:
        self.call(self.listener.on_sent, sent)

    def on_event(self, event: LinkEvent) -> None:
        self.call(self.listener.on_event, event)
