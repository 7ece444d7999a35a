"""No tool attached to a run's hub can hold up the session that records (issue 38 item 2, the hub's part).

The run's real session with a fake agent over real TCP, its real hub on loopback, tools on real sockets: one that
never reads, one whose session stalls (a listener that blocks: a tool on a machine that stopped it), one that reads
everything. The test's thread plays the session's reader thread: it hands the hub frames as the session does.
"""

from __future__ import annotations

import contextlib
import socket
import threading

from groundstation.errors import HubDroppedError
from groundstation.links.hub_events import DROPPED, GROUND_FLAG, parse_ground_text
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import FrameEncoder, StreamDecoder
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.security.attack import attached, hub_run, tool
from tests.waiting import wait_for

QUEUE = 2_000  # frames a tool may fall behind here (the run's own bound is larger: a cheap test)
FED = 60_000  # frames handed to the hub, 250 B each: many times what a queue and the kernel's buffers (4 MB) hold
STEP = 500  # handed at a time, each step once the reading tool has read the one before: it never falls behind
HELLO = m.Hello(protocol_version=1, node_kind=2, definitions_hash=0, firmware_major=0, firmware_minor=0,
                firmware_patch=0, node_id=7, boot_id=7, name="test tool")


def _received() -> Received:
    """One agent TEXT as the session hands it to its listeners (the hub re-frames it for each tool)."""
    wire = FrameEncoder().encode(m.Text(t_us=1, severity=1, text="t" * 230)).wire
    [frame] = StreamDecoder().feed(wire)
    return Received(frame, 0, None, False)


def _hello(sock: socket.socket) -> None:
    """A tool's HELLO, and the hub's answer (the agent's) read: from now on every frame goes to it too."""
    sock.sendall(FrameEncoder().encode(HELLO).wire)
    decoder = StreamDecoder()
    sock.settimeout(10)
    while not any(isinstance(f.message, m.Hello) for f in decoder.feed(sock.recv(4096))):
        pass


class _Stalls:
    """A tool's listener that blocks on the first frame until released: the tool's reader stops reading."""

    def __init__(self) -> None:
        self.release = threading.Event()

    def on_received(self, received: Received) -> None:
        self.release.wait(60)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


def _read_all(sock: socket.socket, frames: list[tuple[int, int, m.Text | None]] | None = None,
              ) -> list[tuple[int, int, m.Text | None]]:
    """(seq, flags, the TEXT) of every frame until the connection ends, appended to `frames` as they come."""
    decoder, frames = StreamDecoder(), [] if frames is None else frames
    sock.settimeout(20)
    with contextlib.suppress(OSError):
        while chunk := sock.recv(65536):
            frames += [(f.seq, f.flags, f.message if isinstance(f.message, m.Text) else None)
                       for f in decoder.feed(chunk)]
    return frames


def test_a_tool_that_stops_reading_holds_up_nobody_and_is_dropped_with_a_reason() -> None:
    """The hub encoded every frame for every tool on the session's reader thread, under the lock its own thread
    held while it served the tools (replays, commands); a stalled tool was closed without a word. Now the reader
    only queues: with the hub's thread held, every frame is still handed over; a tool that falls a queue behind is
    dropped (counted), one that reads again is told why first, and the one that reads gets every frame, no hole."""
    agent = FakeAgent(period_s=1.0)
    try:
        with hub_run(agent.url, tool_queue_frames=QUEUE) as (session, hub, info):
            stalled = attached(info)
            _hello(stalled)
            reader = attached(info)
            _hello(reader)
            got: list[tuple[int, int, m.Text | None]] = []
            reading = threading.Thread(target=_read_all, args=(reader, got), daemon=True)
            reading.start()
            slow = tool()
            slow.connect()
            stalls = _Stalls()
            slow.add_listener(stalls)
            assert hub.client_count == 3

            received, handed = _received(), [0]

            [slow_side] = [c for c in hub._clients if c.tool == "dive"]  # the hub's end of the stalled session

            def feed() -> None:
                for _ in range(FED // STEP):
                    if not wait_for(lambda: len(got) >= handed[0], 20):
                        return  # the reading tool fell behind: the asserts below say so
                    for _ in range(STEP):
                        hub.on_received(received)
                        handed[0] += 1
                    if slow_side.outbox is not None and slow_side.outbox.too_slow:
                        stalls.release.set()  # a queue behind: dropped; it reads again, in time to be told why

            with hub._lock:  # the hub's thread busy for a tool (a replay, a command): the reader must not wait
                feeding = threading.Thread(target=feed, daemon=True)
                feeding.start()
                feeding.join(60)
                handed_while_held = handed[0]
            stalls.release.set()
            assert handed_while_held == FED, f"the reader waited for the hub: {handed_while_held} of {FED} handed"

            # the stalled session reads again: what was on its way, then why, then its session stops in one line
            assert wait_for(lambda: slow.failure is not None, 20), "the slow tool was not told it was dropped"
            assert isinstance(slow.failure, HubDroppedError) and "dropped this tool" in str(slow.failure)
            assert "\n" not in str(slow.failure)
            slow.close()

            assert wait_for(lambda: hub.dropped_slow == 2, 20), hub.dropped_slow
            never = _read_all(stalled)  # the one that never read: a run of frames without a hole, then closed
            seqs = [seq for seq, _, _ in never]
            assert 0 < len(seqs) < FED and seqs == list(range(seqs[0], seqs[0] + len(seqs)))
            said = [parse_ground_text(t.text, (DROPPED,)) for _, f, t in never if t is not None and f & GROUND_FLAG]
            assert all(s is not None and s[2]["behind"] > QUEUE for s in said)  # if it came in time, it says so

            assert wait_for(lambda: len(got) >= FED + 1)  # every frame after the agent's HELLO
            reader.shutdown(socket.SHUT_RDWR)  # its turn to go
            reading.join(20)
            texts = [seq for seq, flags, text in got if text is not None and not flags & GROUND_FLAG]
            assert len(texts) == FED
            seqs = [seq for seq, _, _ in got]
            assert all((b - a) % 65536 == 1 for a, b in zip(seqs, seqs[1:], strict=False)), "a hole in a reader's seq"
            assert wait_for(lambda: hub.client_count == 0) and hub.dropped_slow == 2
    finally:
        agent.close()
