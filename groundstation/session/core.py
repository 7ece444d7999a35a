"""A session's state and its send side: the link, codecs, counters, and commands sent with ACK and retry.

SessionCore holds what the reader thread (session_receive.ReceiveLoop) and the public API (session.Session)
share; a command is registered as pending before its bytes leave, so its ACK can never come back unmatched.
"""

from __future__ import annotations

import os
import threading
import time
from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

from groundstation.errors import AgentBusy, CommandError, CommandTimeout, LinkError
from groundstation.links import Link
from groundstation.session.clock import ClockModel
from groundstation.session.commands import MAYBE_RAN, PendingCommand, PendingCommands, may_have_run, refusal
from groundstation.session.dumps import DumpTracker
from groundstation.session.events import EventKind, LinkEvent, Listeners, Sent, SessionListener
from groundstation.session.exactness import RecentFrames, SampleIndexCheck
from groundstation.session.gaps import BackfillPlanner
from groundstation.session.hello import ground_hello
from groundstation.session.params import ParamTable
from groundstation.session.stats import LinkStats
from protocol import AckResult, FrameEncoder, Message, Mode, Signer, StreamDecoder
from protocol import messages as m
from protocol.signing import RESYNC_NAME, resync_nonce


@dataclass(frozen=True, slots=True)
class SessionConfig:
    hello_timeout_s: float = 5.0
    period_s: float = 1.0  # heartbeat, TIMESYNC and statistics period
    link_timeout_s: float = 3.0  # no frame for this long: the link is lost
    ack_timeout_s: float = 0.5  # first wait for an ACK (3 x measured RTT when that is longer)
    retries: int = 3
    reconnect: bool = True
    backoff_s: tuple[float, float] = (0.2, 5.0)  # first and longest wait between reconnect attempts
    backfill: bool = True
    backfill_retry_s: tuple[float, float] = (1.0, 4.0)  # first and longest wait before a LOG_REQUEST is sent again
    fetch_params: bool = True
    node_id: int = field(default_factory=lambda: int.from_bytes(os.urandom(4), "little"))
    key: bytes | None = field(default=None, repr=False)  # signing key: every frame sent is signed (SPEC s. 12)
    name: str = "dive"  # our HELLO's name: a run's hub names the tool a command came from by it ("dive target")
    # A command answered BUSY (SPEC s. 5; a virtual agent building its program, minutes on a cold compile cache
    # under load) is sent again every BUSY_RETRY_S for this long: waiting, not failing (an AGENT_BUSY event each).
    busy_wait_s: float = 900.0



HELLO_RESEND_S = 1.0  # an unanswered HELLO is sent again after this long (the agent answers every HELLO)
MODE_WAIT_S = 3.0  # for the agent's next SAMPLE or HEARTBEAT (1 Hz of agent time) after a "maybe run" NACK
HELLO_TRIES = 5  # HELLOs unanswered on one connection after a reconnect: that connection is dropped for a new one
BUSY_RETRY_S = 1.0  # a command answered BUSY is sent again after this long, or as soon as the program runs
BUSY_POLL_S = 0.02


class SessionCore:
    def __init__(self, link: Link, config: SessionConfig | None = None,
                 listeners: Iterable[SessionListener] = (), cancel: threading.Event | None = None) -> None:
        """`cancel`, once set (a run stopped by a signal), ends a wait for a BUSY agent at once (AgentBusy)."""
        self.link = link
        self._cancel = cancel or threading.Event()
        # Set when the agent's own program shows it runs (its HELLO, a HEARTBEAT past uptime 0: a starting agent's
        # responder sends uptime 0): a BUSY wait sends again at once, not up to BUSY_RETRY_S later, during which a
        # virtual agent at --speed max would race through idle agent time (and battery).
        self._program_up = threading.Event()
        self.config = config or SessionConfig()
        self.listeners = Listeners(listeners)
        # A random first seq: an agent that remembers the last 16 (msg_id, seq) it ACKed must not take a new
        # session's first commands for retries of the previous session's. A fresh random link id per session, so a
        # new session's clock may lag the last one's a little (SPEC s. 12).
        signer = Signer(self.config.key, os.urandom(1)[0]) if self.config.key is not None else None
        self.encoder = FrameEncoder(first_seq=int.from_bytes(os.urandom(2), "little"), signer=signer)
        self.decoder = StreamDecoder()
        self.stats = LinkStats()
        self.clock = ClockModel()
        self.params = ParamTable()
        self.backfill = BackfillPlanner(*self.config.backfill_retry_s)
        self.dumps = DumpTracker()
        self.agent_hello: m.Hello | None = None
        self.last_heartbeat: m.Heartbeat | None = None
        self.agent_mode: int | None = None  # from the newest live SAMPLE or HEARTBEAT
        self._mode_updates = 0  # how many of those came: a wait for "the mode after this ACK" counts on it
        self._session_starts = 0  # ground HELLOs sent: each starts a session and empties the agent's ACK memory
        self.link_up = False
        self._boot_id = int.from_bytes(os.urandom(4), "little")
        self._start_s = time.monotonic()
        self._cond = threading.Condition()
        self._send_lock = threading.Lock()
        self._pending = PendingCommands()
        self._episodes_seen: set[tuple[int, int, int]] = set()
        self._log_ranges = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_rx_s = 0.0
        self._next_tick_s = 0.0
        self._next_backfill_s = 0.0
        self._next_backfill_view_s = 0.0
        self._retry_backfill_now = False
        self._finish_requested = False
        self._finished_at: int | None = None  # set on the reader thread: the sample index the run ended at
        self._backfill_view: tuple[bool, int, int] = (False, 0, 0)  # (pending, samples held, missing)
        self._restoring = False
        self._hello_problem: str | None = None
        self._hello_resend_s: float | None = None  # while our HELLO is unanswered: when to send it again
        self._hello_tries = 0  # HELLOs sent on this connection since the last answer
        self._resynced = False  # the signed re-sync is tried once per session (SPEC s. 12)
        self._recent = RecentFrames()
        self._timesync_origins: deque[int] = deque(maxlen=8)  # our last TIMESYNC requests: only their answers count
        self.sample_check = SampleIndexCheck()
        self.failure: LinkError | None = None  # why the session stopped by itself (another agent answered)
        self._expected_params = 0
        self._param_updates = 0

    # ------------------------------------------------------------------ commands out
    def send(self, message: Message, *, wait: bool = True, timeout_s: float | None = None,
             flags: int = 0) -> m.Ack | None:
        """Send a message; a command is retried with the same bytes and seq until ACKed. `flags`: frame flags of
        ours (a tool's request to its run's hub is flagged as the ground's: links/hub_events.py).

        With wait, returns the ACK and raises CommandError on a NACK, CommandTimeout without an ACK. A BUSY is
        waited out (busy_wait_s; an AGENT_BUSY event per answer), the command sent again with a new seq: nothing
        ran, and the agent remembers no BUSY (SPEC s. 5).
        """
        started = time.monotonic()
        while True:
            try:
                return self._send_once(message, wait=wait, timeout_s=timeout_s, flags=flags)
            except AgentBusy as e:
                waited_s = time.monotonic() - started
                if waited_s >= self.config.busy_wait_s or self._stop.is_set() or self._cancel.is_set():
                    raise AgentBusy(f"{e} for {waited_s:.0f} s", e.result, e.reason) from e
                self._emit(LinkEvent(EventKind.AGENT_BUSY, time.time_ns(), e.reason,
                                     {"command": message.DEFINITION.name, "waited_s": round(waited_s, 1)}))
                self._program_up.clear()
                deadline = time.monotonic() + BUSY_RETRY_S
                while not (self._cancel.is_set() or self._program_up.is_set()) and time.monotonic() < deadline:
                    self._cancel.wait(BUSY_POLL_S)

    def _send_once(self, message: Message, *, wait: bool, timeout_s: float | None, flags: int) -> m.Ack | None:
        now = time.monotonic()
        ack_timeout_s = self._ack_timeout_s()
        with self._send_lock:
            encoded = self.encoder.encode(message, flags)
            if isinstance(message, m.Hello):
                # Counted under the send lock, with the bytes: a command's bytes then leave wholly before or after
                # this HELLO, and its written_in says which (counted outside, a command written just before it
                # could be filed under the new session, and its retry after the HELLO not read as crossing it).
                self._session_starts += 1
            pending = None
            if message.DEFINITION.needs_ack:
                pending = PendingCommand(message, encoded.seq, encoded.wire, now, now + ack_timeout_s)
                if wait and timeout_s is not None:  # an explicit wait: keep trying (across reconnects) until then
                    pending.give_up_s = now + timeout_s
                self._pending.add(pending)
            try:
                self._write(message, encoded.seq, encoded.wire)
                if pending is not None:
                    pending.written_in = self._session_starts
            except LinkError:
                # A command sent while the link is down (it drops often under water) stays pending: the reader
                # re-sends it once the session has reconnected. Without reconnect there is nobody to do so.
                if pending is None or not self.config.reconnect or self._stop.is_set():
                    raise
        if pending is None or not wait:
            return None
        limit = timeout_s if timeout_s is not None else ack_timeout_s * (self.config.retries + 1) + 1.0
        pending.done.wait(limit)
        name = message.DEFINITION.name
        if pending.ack is None:  # still pending: an ACK would have removed it
            self._pending.discard(pending.seq)
            if not self.link_up and self._stop.is_set():
                raise LinkError(f"{name}: the session is closed")
            self.stats.command_timeouts += 1
            raise CommandTimeout(f"{name}: no ACK from the agent after {pending.attempts} tries")
        if pending.crossed and pending.ack.result in MAYBE_RAN:
            raise may_have_run(name, pending.ack, self._mode_after(pending.mode_mark))
        refused = refusal(name, pending.ack)
        if refused is not None:
            nonce = self._resync_nonce(message, pending.ack)
            if nonce is None:
                raise refused
            try:
                self._resync(nonce)
            except CommandError as e:
                raise refused from e
            return self.send(message, wait=wait, timeout_s=timeout_s)  # once more, with new bytes and seq
        return pending.ack

    def _resync_nonce(self, message: Message, ack: m.Ack) -> int | None:
        """The nonce to re-sync with when the agent refused our timestamp (replayed, too old or too new: a ground
        with a clock far off signed first) and we hold the key and have not re-synced yet; else None."""
        if ack.result != AckResult.UNAUTHORIZED or self.config.key is None or self._resynced:
            return None
        if isinstance(message, m.ParamSet) and message.name == RESYNC_NAME:
            return None
        return resync_nonce(ack.reason)

    def _resync(self, nonce: int) -> None:
        """The signed re-sync (SPEC s. 12): the agent's replay state starts again from our clock; said in one line."""
        self._resynced = True
        ack = self.send(m.ParamSet(index=-1, value=float(nonce), name=RESYNC_NAME))
        assert ack is not None
        self._emit(LinkEvent(EventKind.ERROR, time.time_ns(),
                             "the agent refused our signatures' timestamps (a ground with a clock far off signed "
                             "first): re-synced its signing clock to ours", {"reason": ack.reason}))

    def _mode_after(self, mark: int) -> str:
        """The agent's mode from its first SAMPLE or HEARTBEAT after `mark` (the newest known if none comes)."""
        deadline = time.monotonic() + MODE_WAIT_S
        while self._mode_updates <= mark and not self._stop.is_set() and time.monotonic() < deadline:
            time.sleep(0.02)
        mode = self.agent_mode
        if mode is None:
            return "in an unknown mode"
        return Mode(mode).name if mode in Mode._value2member_map_ else f"in mode {mode}"

    # ------------------------------------------------------------------ helpers
    def _ack_timeout_s(self) -> float:
        rtt = self.stats.rtt_median_s()
        return max(self.config.ack_timeout_s, 3 * rtt) if rtt is not None else self.config.ack_timeout_s

    def _send_hello(self) -> None:
        self._hello_resend_s = time.monotonic() + HELLO_RESEND_S
        self._hello_tries += 1
        self.send(ground_hello(self.config.node_id, self._boot_id, self.config.name))

    def _write(self, message: Message, seq: int, wire: bytes, retry: bool = False) -> None:
        self.link.send(wire)
        self.stats.sent(len(wire), retry)
        self.listeners.sent(Sent(seq, message, wire, time.time_ns()))

    def _emit_stats(self) -> None:
        data = {"link": self.stats.snapshot(self.decoder.stats), "clock": self.clock.as_dict()}
        self._emit(LinkEvent(EventKind.STATS, time.time_ns(), "", data))

    def _emit(self, event: LinkEvent) -> None:
        self.listeners.event(event)

    def _hello_data(self) -> dict[str, object]:
        return self.agent_hello.to_dict() if self.agent_hello else {}

