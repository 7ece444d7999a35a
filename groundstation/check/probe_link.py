"""The checks' hands on the link: raw frames out (valid or not), every frame in, kept in order, and commands.

Unlike a Session, it never retries, never answers and never hides a frame: a check decides what goes out (wrong
CRCs, repeated seqs, unknown ids, truncated signatures) and reads exactly what came back. What the frames say of the
agent's mode is probe.py's job.
"""

from __future__ import annotations

import os
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import TypeVar

from groundstation.check.errors import CheckFailed
from groundstation.errors import LinkError
from groundstation.links import Link
from protocol import AckResult, FrameFlag, Message, Signer, StreamDecoder
from protocol import messages as m
from protocol.cobs import cobs_encode
from protocol.decoder import Frame
from protocol.frame import HEADER, build_inner, payload_end

COMMAND_IDS_FROM = 0x80
KEEPALIVE_S = 0.5  # the probe sends a HEARTBEAT after this much silence (an agent may surface on link loss)
KEPT_FRAMES = 200_000  # frames kept for look-ups; a fast virtual agent sends tens of thousands a second
ACK_REQUESTED = int(FrameFlag.ACK_REQUESTED)
REPLAYED = int(FrameFlag.REPLAYED)
_SIGNED = int(FrameFlag.SIGNED)
T = TypeVar("T", bound=Message)


@dataclass(frozen=True)
class Timeouts:
    """How long the probe waits, in wall seconds (a real agent over a slow link needs more than the virtual one)."""

    reply_s: float = 2.0  # an ACK, a reply, a TIMESYNC answer
    heartbeat_s: float = 3.0  # the agent's next HEARTBEAT (about once per second of agent time)
    mode_s: float = 60.0  # a mode change that takes the agent time (surfacing, recovery)


@dataclass
class Exchange:
    """A command sent and what answered it: the ACK and where it sits among the received frames."""

    msg_id: int
    seq: int
    inner: bytes
    sent_at: int  # index of the first frame received after sending
    ack: m.Ack | None = None
    ack_at: int = -1  # index of the ACK among the received frames

    @property
    def result(self) -> int | None:
        return self.ack.result if self.ack is not None else None


class LinkProbe:
    """Sends frames of the check's choosing through a link and keeps everything the agent sends, in order."""

    def __init__(self, link: Link, key: bytes | None = None, timeouts: Timeouts | None = None) -> None:
        self.link = link
        self.key = key
        self.timeouts = timeouts or Timeouts()
        self.signer = Signer(key, os.urandom(1)[0]) if key is not None else None
        self._seq = int.from_bytes(os.urandom(2), "little")
        self.decoder = StreamDecoder()
        self._frames: deque[Frame] = deque()
        self._first = 0  # absolute index of _frames[0]
        self.hello: m.Hello | None = None
        self.sent_valid = 0  # frames sent that an agent must count in rx_frames
        self.keepalive = True
        self._last_send_s = time.monotonic()
        self._origin = 0
        self._held = b""  # a deferred frame, sent with the next one
        self._writes = 0  # link writes so far: counters read after the last one are still current
        self._counters: tuple[tuple[int, int], m.Heartbeat] | None = None
        self.notes: dict[str, float | None] = {}  # what checks learned about the agent (shared between checks)
        self.originals: dict[str, float | None] = {}  # parameter values to put back at the end of the run

    # ------------------------------------------------------------------ frames out
    def next_seq(self) -> int:
        seq = self._seq
        self._seq = (seq + 1) & 0xFFFF
        return seq

    @property
    def upcoming_seq(self) -> int:
        """The seq the next frame will carry (not taken)."""
        return self._seq

    def skip_seqs(self, count: int) -> None:
        """Leave `count` seqs unused: the agent must count them as lost."""
        self._seq = (self._seq + count) & 0xFFFF

    def inner(self, msg_id: int, payload: bytes, flags: int = 0, *, seq: int | None = None,
              signer: Signer | None | bool = True) -> bytes:
        """An inner frame; `signer` True = the probe's own signer (if it has a key), False/None = unsigned."""
        chosen = self.signer if signer is True else (signer or None)
        trailer = chosen.trailer if isinstance(chosen, Signer) else None
        return build_inner(flags, self.next_seq() if seq is None else seq, msg_id, payload, trailer)

    def send_inner(self, inner: bytes, valid: bool = True) -> None:
        """Send one inner frame (COBS-encoded, delimited); `valid` = the agent must count it in rx_frames."""
        self.send_raw(cobs_encode(inner) + b"\x00")
        if valid:
            self.sent_valid += 1

    def send_raw(self, data: bytes) -> None:
        """Write bytes; a deferred frame (see defer) goes out first, in the same write."""
        held, self._held = self._held, b""
        self.link.send(held + data)
        self._last_send_s = time.monotonic()
        self._writes += 1

    def send(self, message: Message, flags: int | None = None, *, seq: int | None = None,
             signer: Signer | None | bool = True) -> bytes:
        """Send a message (commands get ACK_REQUESTED unless `flags` says otherwise); returns its inner frame."""
        if flags is None:
            flags = ACK_REQUESTED if message.MSG_ID >= COMMAND_IDS_FROM else 0
        inner = self.inner(message.MSG_ID, message.pack(), flags, seq=seq, signer=signer)
        self.send_inner(inner)
        return inner

    def retry_inner(self, inner: bytes, signer: Signer | None | bool = True) -> bytes:
        """A retry of a sent frame: the same seq and payload; a signed frame gets a fresh trailer (SPEC.md 12)."""
        chosen = self.signer if signer is True else (signer or None)
        if not inner[1] & _SIGNED and chosen is None:
            return inner
        flags = inner[1] & ~_SIGNED
        payload = inner[HEADER.size : payload_end(inner)]
        seq = int.from_bytes(inner[2:4], "little")
        return build_inner(flags, seq, inner[4], payload, chosen.trailer if isinstance(chosen, Signer) else None)

    @property
    def last_send_s(self) -> float:
        """When (time.monotonic) the probe last wrote to the link: no agent heard from it since before then."""
        return self._last_send_s

    # ------------------------------------------------------------------ frames in
    @property
    def first(self) -> int:
        """Index of the oldest received frame still kept."""
        return self._first

    @property
    def end(self) -> int:
        """Index the next received frame will get."""
        return self._first + len(self._frames)

    def frame(self, index: int) -> Frame:
        return self._frames[index - self._first]

    def frames(self, start: int, end: int | None = None) -> list[Frame]:
        stop = self.end if end is None else end
        begin = max(start, self._first)
        return [self._frames[i - self._first] for i in range(begin, stop)]

    def pump(self, timeout_s: float = 0.0) -> int:
        """Read what the link has (waiting at most timeout_s); returns how many frames arrived."""
        if self._held:  # a deferred command nobody sent a frame behind: it goes now, on its own
            self._held_sent_alone()
            self.send_raw(b"")
        if self.keepalive and time.monotonic() - self._last_send_s > KEEPALIVE_S:
            self.send(self._ground_heartbeat())
        data = self.link.recv(timeout_s)
        if not data:
            return 0
        frames = self.decoder.feed(data)
        for frame in frames:
            if isinstance(frame.message, m.Hello):
                self.hello = frame.message
            self._seen(frame)
            self._frames.append(frame)
        while len(self._frames) > KEPT_FRAMES:
            self._frames.popleft()
            self._first += 1
        return len(frames)

    def drain(self, most: int = 200) -> None:
        """Read what has already arrived (at most `most` reads): the newest frames show the agent's present."""
        for _ in range(most):
            if not self.pump(0.0):
                return

    def wait(self, predicate: Callable[[Frame], bool], start: int, timeout_s: float) -> tuple[int, Frame] | None:
        """The first frame at or after index `start` that satisfies predicate, pumping up to timeout_s."""
        deadline = time.monotonic() + timeout_s
        index = max(start, self._first)
        last_read = False
        while True:
            while index < self.end:
                frame = self._frames[index - self._first]
                if predicate(frame):
                    return index, frame
                index += 1
            if last_read:
                return None
            remaining = deadline - time.monotonic()
            # One read more once the time is up, whatever the scan cost: an agent at --speed max runs only while
            # its frames are read, so a wait that returned unread could hold it still.
            last_read = remaining <= 0
            self.pump(max(0.0, min(remaining, 0.05)))

    def wait_message(self, kind: type[T], start: int, timeout_s: float,
                     where: Callable[[T], bool] = lambda _: True) -> tuple[int, T] | None:
        found = self.wait(lambda f: isinstance(f.message, kind) and where(f.message), start, timeout_s)  # type: ignore[arg-type]
        if found is None:
            return None
        index, frame = found
        return index, frame.message  # type: ignore[return-value]

    def messages(self, kind: type[T], start: int, end: int | None = None) -> list[T]:
        return [f.message for f in self.frames(start, end) if isinstance(f.message, kind)]  # type: ignore[misc]

    def settle(self, seconds: float) -> None:
        """Keep reading for `seconds` (late or unwanted frames get their chance to show up)."""
        deadline = time.monotonic() + seconds
        while (remaining := deadline - time.monotonic()) > 0:
            self.pump(min(remaining, 0.05))

    # ------------------------------------------------------------------ commands
    def command(self, message: Message, flags: int | None = None, *, seq: int | None = None,
                signer: Signer | None | bool = True, timeout_s: float | None = None) -> Exchange:
        """Send a command and wait for the ACK that echoes its msg_id and seq (ack None if none came)."""
        start = self.end
        inner = self.send(message, flags, seq=seq, signer=signer)
        return self.await_ack(Exchange(message.MSG_ID, int.from_bytes(inner[2:4], "little"), inner, start), timeout_s)

    def command_inner(self, inner: bytes, timeout_s: float | None = None, valid: bool = True) -> Exchange:
        """Send a ready-made command frame (a retry, a forged trailer) and wait for its ACK."""
        start = self.end
        self.send_inner(inner, valid)
        return self.await_ack(Exchange(inner[4], int.from_bytes(inner[2:4], "little"), inner, start), timeout_s)

    def burst(self, messages: list[Message]) -> list[Exchange]:
        """Send commands in one write, without waiting in between (the agent handles them back to back, within a
        step or two of each other), and wait for each one's ACK."""
        start = self.end
        inners = [self.inner(msg.MSG_ID, msg.pack(), ACK_REQUESTED) for msg in messages]
        self.send_raw(b"".join(cobs_encode(inner) + b"\x00" for inner in inners))
        self.sent_valid += len(inners)
        sent = [Exchange(inner[4], int.from_bytes(inner[2:4], "little"), inner, start) for inner in inners]
        return [self.await_ack(ex) for ex in sent]

    def await_ack(self, ex: Exchange, timeout_s: float | None = None) -> Exchange:
        found = self.wait_message(m.Ack, ex.sent_at, self.timeouts.reply_s if timeout_s is None else timeout_s,
                                  lambda a: a.cmd_msg_id == ex.msg_id and a.cmd_seq == ex.seq)
        if found is not None:
            ex.ack_at, ex.ack = found
        return ex

    def accepted(self, message: Message, what: str = "") -> Exchange:
        """A command that must be ACCEPTED for the check to go on (CheckFailed naming it otherwise)."""
        ex = self.command(message)
        name = what or message.DEFINITION.name
        if ex.ack is None:
            raise CheckFailed(f"{name}: no ACK within {self.timeouts.reply_s:g} s")
        if ex.ack.result != 0:
            raise CheckFailed(f"{name}: refused with {result_name(ex.ack.result)} ({ex.ack.reason})")
        return ex

    def acks_for(self, ex: Exchange, end: int | None = None) -> list[m.Ack]:
        return [a for a in self.messages(m.Ack, ex.sent_at, end) if a.cmd_msg_id == ex.msg_id and a.cmd_seq == ex.seq]

    # ------------------------------------------------------------------ synchronisation
    def barrier(self) -> int:
        """TIMESYNC round trip: every frame sent before it has been handled; returns the reply's index."""
        self._origin += 1
        origin = self._origin
        start = self.end
        self.send(m.Timesync(origin_us=origin, receive_us=0, transmit_us=0))
        found = self.wait_message(m.Timesync, start, self.timeouts.reply_s,
                                  lambda t: t.origin_us == origin and t.transmit_us != 0)
        if found is None:
            raise CheckFailed(f"no TIMESYNC reply within {self.timeouts.reply_s:g} s (used to synchronise)")
        return found[0]

    def counters(self) -> m.Heartbeat:
        """The agent's counters after everything sent so far: the first HEARTBEAT after a barrier.

        No keep-alive goes out meanwhile: the agent would count it after the HEARTBEAT that is read here. Nothing
        sent and no seq skipped since the last reading: that reading (a real agent sends one HEARTBEAT a second).
        """
        if self._counters is not None and self._counters[0] == (self._writes, self._seq) and not self._held:
            return self._counters[1]
        with self.quiet():
            after = self.barrier()
            found = self.wait_message(m.Heartbeat, after, self.timeouts.heartbeat_s)
        if found is None:
            raise CheckFailed(f"no HEARTBEAT within {self.timeouts.heartbeat_s:g} s")
        self._counters = ((self._writes, self._seq), found[1])
        return found[1]

    @contextmanager
    def quiet(self) -> Iterator[None]:
        """No keep-alive HEARTBEATs inside (a check counting frames or letting the link go silent)."""
        before, self.keepalive = self.keepalive, False
        try:
            yield
        finally:
            self.keepalive = before

    def _ground_heartbeat(self) -> m.Heartbeat:
        rx = self.decoder.stats
        return m.Heartbeat(uptime_ms=int(time.monotonic() * 1000) & 0xFFFFFFFF, mode=0, battery_mv=0,
                           rx_frames=rx.frames & 0xFFFFFFFF, rx_rejects=rx.rejects & 0xFFFFFFFF,
                           rx_lost=rx.lost & 0xFFFFFFFF, log_first_sample=0, log_next_sample=0, episode=0,
                           signing_rejects=0)

    # ------------------------------------------------------------------ what a subclass follows
    def _seen(self, frame: Frame) -> None:
        """Each frame as it arrives, before it is kept (Probe follows the agent's mode in it)."""

    def _held_sent_alone(self) -> None:
        """A deferred command goes out on its own, without the frame it was held for."""

    def close(self) -> None:
        try:
            self.link.close()
        except LinkError:
            pass


def result_name(result: int | None) -> str:
    """An ACK result by name ("no ACK" for None)."""
    if result is None:
        return "no ACK"
    try:
        return AckResult(result).name
    except ValueError:
        return f"result {result}"
