"""One tool's way out of the hub: its frames queued from any thread, written to its socket by a thread of its own.

The hub used to encode every frame for every tool on the session's reader thread, under the lock the hub's own
thread held while it wrote to the tools and encoded their history replays: the thread that feeds the recorder and
answers the agent paid for each tool. Now the reader thread only appends one entry per frame, built once, to each
tool's queue, and each tool's writer thread encodes with the tool's own seq (so its loss count is its own link's)
and blocks in send as long as that tool is slow: nobody else waits for it.

The queue is bounded (TOOL_QUEUE_FRAMES). A tool counts frames by sequence number, so it is never handed a silent
hole: a tool whose queue is full is dropped instead. What was queued for it is let go, it is sent what was already on
its way and then a ground TEXT saying why (links/hub_events.py `dropped`; its session stops on it with that line, as
on the agent's "link taken" TEXT), given REASON_WAIT_S to read them, and closed. The run counts it (Hub.dropped_slow).
A tool that does not read again within REASON_WAIT_S is closed without the reason (it is not reading it anyway).
"""

from __future__ import annotations

import select
import socket
import threading
import time
from collections.abc import Callable
from typing import Any

from groundstation.links.hub_events import GROUND_FLAG, dropped_text
from groundstation.session.handoff import Outbox
from protocol import FrameEncoder, Message

# Frames queued for one tool (a history replay counts each of its frames; the history holds at most 2 MiB, about
# 30 000): over a minute behind at the virtual agent's --speed 100, more than an hour at the agent's own rate.
# A queued frame costs each tool 8 bytes, and the run about 220 B once, however many tools hold it: 16 tools a whole
# queue behind hold about 8 MB of references and 15 MB of frames.
TOOL_QUEUE_FRAMES = 65_536
BATCH_FRAMES = 256  # encoded and sent at a time: what is already on its way when a tool is found too slow
REASON_WAIT_S = 10.0  # a tool dropped for falling behind gets this long to read what was on its way, and why
_POLL_MS = 250

AgentFrame = tuple[int, bytes, int]  # (msg_id, payload, flags)


def frame_entry(frame: AgentFrame) -> tuple[None, AgentFrame, int]:
    """The queue entry of one agent frame, built once and put in every tool's queue (ToolOutbox.put_frame): a tool
    far behind then costs 8 bytes a frame, not a call of its own (a tuple and a bound method: 130 B a tool)."""
    return (None, frame, 1)


class ToolOutbox(Outbox):
    """What the hub sends one tool (the agent's frames re-framed, answers, replays), in order, from its own thread.

    `on_end` (the hub's wake-up) is called from this thread when it ends: dropped for falling behind, the tool gone,
    or closed by the hub. The hub closes the socket after that, never this thread (its fd could be reused)."""

    batch_limit = BATCH_FRAMES

    def __init__(self, sock: socket.socket, encoder: FrameEncoder, name: str, on_end: Callable[[], None],
                 capacity: int = TOOL_QUEUE_FRAMES) -> None:
        self.sock = sock
        self.encoder = encoder
        self.behind: int | None = None  # frames it was behind when dropped for not keeping up; None: never
        self._out = bytearray()
        self._drop_by: float | None = None  # monotonic time by which an overflowed tool has read its last frames
        self._on_end = on_end
        self._let_go = threading.Event()  # the hub is done with it (the tool closed, or the run ends)
        self._poll = select.poll()
        self._poll.register(sock, select.POLLOUT)
        super().__init__(capacity, name)

    # ------------------------------------------------------------------ any thread (the session's reader above all)
    def put_frame(self, entry: tuple[None, AgentFrame, int]) -> None:
        self._put(entry)

    def message(self, message: Message, flags: int = 0) -> None:
        self.call(self._message, (message, flags))

    def frames(self, items: list[tuple[int, bytes]], flags: int) -> None:
        """A history replay: one call, as many frames of the queue as it holds."""
        self.call(self._frames, (items, flags), weight=max(1, len(items)))

    def _full(self, weight: int) -> None:
        # Called holding the queue's lock, on the thread that queued (the reader's): no I/O here, only letting go.
        self.behind = self._queued + weight
        self.dropped += self._queued + weight
        self._queue.clear()
        self._queued = 0
        self._closed = True
        self._drop_by = time.monotonic() + REASON_WAIT_S
        self._ready.notify()

    @property
    def too_slow(self) -> bool:
        return self.behind is not None

    # ------------------------------------------------------------------ this object's thread
    def _run(self, method: Callable[[Any], None] | None, item: object) -> None:
        if method is None:
            self._frame(item)  # type: ignore[arg-type]  # frame_entry's
        else:
            method(item)

    def _frame(self, item: AgentFrame) -> None:
        self._out += self.encoder.encode_payload(*item).wire

    def _message(self, item: tuple[Message, int]) -> None:
        self._out += self.encoder.encode(item[0], item[1]).wire

    def _frames(self, item: tuple[list[tuple[int, bytes]], int]) -> None:
        items, flags = item
        for msg_id, payload in items:
            self._out += self.encoder.encode_payload(msg_id, payload, flags).wire

    def _delivered(self) -> None:
        try:
            self._flush()
        except OSError as e:  # the tool is gone, or the hub shut its socket
            self.failure = f"{type(e).__name__}: {e}"

    def _flush(self) -> bool:
        """Send what is encoded; blocks while the tool does not read, until it does, the socket is shut, or (once
        dropped for falling behind) REASON_WAIT_S is over. False: it was not all sent in time."""
        out, done = self._out, 0
        try:
            while done < len(out):
                try:
                    with memoryview(out)[done:] as view:
                        done += self.sock.send(view)
                except (BlockingIOError, InterruptedError):
                    if self._drop_by is not None and time.monotonic() > self._drop_by:
                        return False
                    self._poll.poll(_POLL_MS)
            return True
        finally:
            del out[:done]

    def _ended(self) -> None:
        try:
            if self.too_slow and self.failure is None:
                self._out += self.encoder.encode(dropped_text(self.behind or 0), GROUND_FLAG).wire
                if self._flush():
                    # Only our side closed: the tool reads to the reason and the end, and it is its close that ends
                    # the connection. Closed both ways at once, a tool still sending (a HEARTBEAT) would fail its
                    # send and drop its link before it read why.
                    self.sock.shutdown(socket.SHUT_WR)
                    self._let_go.wait(REASON_WAIT_S)
        except OSError:
            pass  # gone already: it cannot be told
        finally:
            self._on_end()

    def close(self, timeout_s: float = 2.0) -> None:
        self._let_go.set()
        super().close(timeout_s)
