"""A session with one agent: HELLO, heartbeats, TIMESYNC, commands with ACK and retry, params, dumps, backfill.

One reader thread owns the link's receive side and every timer; it never dies: transport errors become
LinkEvents (link lost / restored / resynced) and it reconnects with backoff; a listener's exception is
caught and reported as an ERROR event. Commands may be sent from any thread except listeners' callbacks
(their ACK arrives on the reader thread); send(..., wait=False) is the form for those.
"""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

from groundstation.clock import ClockModel
from groundstation.commands import PendingCommand, PendingCommands, refusal
from groundstation.dumps import Dump, DumpTracker
from groundstation.errors import (
    AgentChangedError,
    CommandError,
    CommandTimeout,
    IncompatibleAgentError,
    LinkError,
    LinkTimeout,
    ParameterError,
)
from groundstation.events import EventKind, LinkEvent, Listeners, Received, ReceivedCallback, Sent, SessionListener
from groundstation.exactness import RecentFrames, SampleIndexCheck
from groundstation.gaps import BackfillPlanner
from groundstation.hello import ground_hello, incompatibility
from groundstation.links import Link
from groundstation.params import Parameter, ParamTable, load_cached, parse_value, save_cached
from groundstation.safe_output import one_line
from groundstation.stats import LinkStats
from protocol import (
    DumpKind,
    Frame,
    FrameEncoder,
    FrameFlag,
    Message,
    Mode,
    Signer,
    StreamDecoder,
)
from protocol import messages as m


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


_SEQUENCED = (m.EpisodeStart, m.EpisodeEnd)
_WAITED_FOR = (m.Sample, m.LogRange, m.EpisodeStart, m.EpisodeEnd)  # what request_backfill's waiter looks at
HELLO_RESEND_S = 1.0  # an unanswered HELLO is sent again after this long (the agent answers every HELLO)


class Session:
    def __init__(self, link: Link, config: SessionConfig | None = None,
                 listeners: Iterable[SessionListener] = ()) -> None:
        self.link = link
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
        self._recent = RecentFrames()
        self.sample_check = SampleIndexCheck()
        self.failure: LinkError | None = None  # why the session stopped by itself (another agent answered)
        self._expected_params = 0
        self._param_updates = 0

    # ------------------------------------------------------------------ life cycle
    def connect(self) -> m.Hello:
        """Open the link, exchange HELLO (version and hash checked), fetch the parameter table."""
        self.link.open()
        self._last_rx_s = time.monotonic()
        self._thread = threading.Thread(target=self._run, name="dive-session-reader", daemon=True)
        self._thread.start()
        try:
            self._send_hello()
            with self._cond:
                ok = self._cond.wait_for(lambda: self.agent_hello is not None or self._hello_problem is not None,
                                         self.config.hello_timeout_s)
            if self._hello_problem is not None:
                raise IncompatibleAgentError(self._hello_problem)
            if not ok or self.agent_hello is None:
                raise LinkTimeout(f"{self.link.url}: no HELLO from the agent within {self.config.hello_timeout_s:g} s")
            self.link_up = True
            self._emit(LinkEvent(EventKind.CONNECTED, time.time_ns(), self.link.url, self._hello_data()))
            if self.config.fetch_params:
                self.refresh_params()
        except BaseException:
            self.close()
            raise
        return self.agent_hello

    def close(self) -> None:
        self._stop.set()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(5.0)
        if self.agent_hello is not None:  # the recording ends with the final link statistics, not 1 s old ones
            self._emit_stats()
        self.link.close()
        self.link_up = False
        self._pending.release_all()
        with self._cond:
            self._cond.notify_all()

    def __enter__(self) -> Session:
        self.connect()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def add_listener(self, listener: SessionListener) -> None:
        self.listeners.add(listener)

    def mark(self, text: str) -> None:
        """A user marker: goes to every listener (the recorder writes it to /marker)."""
        self._emit(LinkEvent(EventKind.MARKER, time.time_ns(), text, {"text": text}))

    # ------------------------------------------------------------------ commands
    def send(self, message: Message, *, wait: bool = True, timeout_s: float | None = None) -> m.Ack | None:
        """Send a message; a command is retried with the same bytes and seq until ACKed.

        With wait, returns the ACK and raises CommandError on a NACK, CommandTimeout without an ACK.
        """
        now = time.monotonic()
        ack_timeout_s = self._ack_timeout_s()
        with self._send_lock:
            encoded = self.encoder.encode(message)
            pending = None
            if message.DEFINITION.needs_ack:
                pending = PendingCommand(message, encoded.seq, encoded.wire, now, now + ack_timeout_s)
                if wait and timeout_s is not None:  # an explicit wait: keep trying (across reconnects) until then
                    pending.give_up_s = now + timeout_s
                self._pending.add(pending)
            try:
                self._write(message, encoded.seq, encoded.wire)
            except LinkError:
                # A command sent while the link is down (it drops often under water) stays pending: the reader
                # re-sends it once the session has reconnected. Without reconnect there is nobody to do so.
                if pending is None or not self.config.reconnect or self._stop.is_set():
                    raise
        if pending is None or not wait:
            return None
        limit = timeout_s if timeout_s is not None else ack_timeout_s * (self.config.retries + 1) + 1.0
        pending.done.wait(limit)
        self._pending.discard(pending.seq)
        name = message.DEFINITION.name
        if pending.ack is None:
            if not self.link_up and self._stop.is_set():
                raise LinkError(f"{name}: the session is closed")
            self.stats.command_timeouts += 1
            raise CommandTimeout(f"{name}: no ACK from the agent after {pending.attempts} tries")
        refused = refusal(name, pending.ack)
        if refused is not None:
            raise refused
        return pending.ack

    def command(self, message: Message, timeout_s: float | None = None) -> m.Ack:
        ack = self.send(message, wait=True, timeout_s=timeout_s)
        assert ack is not None
        return ack

    def refresh_params(self, timeout_s: float = 3.0) -> ParamTable:
        """PARAM_LIST, wait for the whole table; fall back to the disk cache if the agent stays silent."""
        assert self.agent_hello is not None
        key = (self.agent_hello.definitions_hash, self.agent_hello.node_id)
        try:
            self.command(m.ParamListRequest())
            with self._cond:
                self._cond.wait_for(lambda: self._expected_params and len(self.params) >= self._expected_params,
                                    timeout_s)
        except CommandError:
            cached = load_cached(*key)
            if cached is None:
                raise
            self.params = cached
            return cached
        save_cached(self.params, *key)
        return self.params

    def get_param(self, name: str, timeout_s: float = 2.0) -> Parameter:
        if len(self.params):
            self.params.get(name)  # an unknown name: the same "did you mean" as set_param, before asking the agent
        before = self._param_updates
        self.command(m.ParamGet(index=-1, name=name))
        with self._cond:
            self._cond.wait_for(lambda: self._param_updates > before and name in self.params, timeout_s)
        return self.params.get(name)

    def set_param(self, name: str, value: float | str, timeout_s: float = 2.0) -> Parameter:
        """Set a parameter by name (checked against the table first); returns the value the agent applied."""
        param = self.params.get(name) if len(self.params) else None
        number = parse_value(param, str(value)) if param else float(value)
        before = self._param_updates
        try:
            self.command(m.ParamSet(index=-1, value=number, name=name))
        except CommandError as e:
            if "BAD_VALUE" in str(e):
                raise ParameterError(f"{name} = {value}: {e}") from e
            raise
        with self._cond:
            self._cond.wait_for(lambda: self._param_updates > before, timeout_s)
        return self.params.get(name)

    def dump(self, kind: DumpKind, timeout_s: float = 5.0) -> Dump:
        """Take a snapshot and reassemble it, re-requesting missing chunks (SPEC.md section 10)."""
        asked = time.monotonic()
        self.command(m.DumpRequest(kind=int(kind), dump_id=0, offset=0, length=0))
        deadline = asked + timeout_s

        with self._cond:
            while time.monotonic() < deadline:
                done = self.dumps.newest_since(kind, asked)
                if done is not None:
                    return done
                self._cond.wait(0.05)
        raise CommandTimeout(f"CMD_DUMP {kind.name}: snapshot incomplete after {timeout_s:g} s")

    def request_backfill(self, timeout_s: float = 5.0, limit_s: float | None = None, final: bool = False) -> int:
        """Ask for every missing sample now and wait until none the agent holds is missing; returns how many are.

        `final`: the run is over. The recording then ends where the agent is now: live frames are no longer
        handed to listeners and only the samples below that point are fetched (the agent goes on sampling in
        IDLE; a tail that grows faster than a lossy link can backfill it would otherwise never be complete).

        The wait ends `timeout_s` after the last progress (a sample or episode frame filled in), or after `limit_s`
        in all (default: 6 x timeout_s), or when the link is down with no reconnect to wait for. The planner
        belongs to the reader thread; this thread sees only what it publishes (`_backfill_view`).
        """
        self._retry_backfill_now = True
        self._finish_requested = self._finish_requested or final
        now = time.monotonic()
        hard_deadline = now + (limit_s if limit_s is not None else 6 * timeout_s)
        deadline, held = now + timeout_s, -1
        with self._cond:
            self._cond.wait_for(lambda: not self._retry_backfill_now or self._stop.is_set(), 2.0)
            while self._backfill_view[0] and time.monotonic() < min(deadline, hard_deadline):
                if not self.link_up and (not self.config.reconnect or self._stop.is_set()):
                    break
                self._cond.wait(0.1)
                if self._backfill_view[1] != held:
                    deadline, held = time.monotonic() + timeout_s, self._backfill_view[1]
            return self._backfill_view[2]

    @property
    def samples_held(self) -> int:
        """Distinct SAMPLE indices received (as last published by the reader thread, at most 0.1 s old)."""
        return self._backfill_view[1]

    def backfill_status(self) -> tuple[int, int]:
        """(lost, still held): missing samples the agent's log no longer holds, and those it still does."""
        lost = self.backfill.lost()
        return lost, sum(b - a for a, b in self.backfill.missing()) - lost

    # ------------------------------------------------------------------ the reader thread
    def _run(self) -> None:
        backoff = self.config.backoff_s[0]
        while not self._stop.is_set():
            try:
                if not self.link.is_open:
                    if not self.config.reconnect:
                        self._stop.wait(0.2)
                        continue
                    self._stop.wait(backoff)
                    if self._stop.is_set():
                        break
                    try:
                        self._reconnect()
                        backoff = self.config.backoff_s[0]
                    except LinkError:
                        backoff = min(backoff * 2, self.config.backoff_s[1])
                    continue
                data = self.link.recv(0.05)
                now_ns = time.time_ns()
                if data:
                    self._last_rx_s = time.monotonic()
                    for frame in self.decoder.feed(data):
                        self._handle(frame, now_ns)
                self._tick(time.monotonic())
            except LinkError as e:
                self._lost(str(e))
            except Exception as e:  # the reader must survive anything; the user sees it as an event
                self._emit(LinkEvent(EventKind.ERROR, time.time_ns(), f"{type(e).__name__}: {e}"))
                self._stop.wait(0.05)

    def _lost(self, reason: str) -> None:
        was_up = self.link_up
        self.link_up = False
        self.link.drop()
        if was_up:
            self._emit(LinkEvent(EventKind.LINK_LOST, time.time_ns(), reason))
        with self._cond:
            self._cond.notify_all()

    def _reconnect(self) -> None:
        if self._stop.is_set():
            return
        self.link.reconnect()
        self.decoder = StreamDecoder(stats=self.decoder.stats)
        self._last_rx_s = time.monotonic()
        self._restoring = True
        self._recent.clear()
        self.stats.reconnects += 1
        self._send_hello()

    def _tick(self, now_s: float) -> None:
        if self.agent_hello is not None and now_s - self._last_rx_s > self.config.link_timeout_s:
            raise LinkError(f"no frame from the agent for {self.config.link_timeout_s:g} s")
        if self._hello_resend_s is not None and now_s >= self._hello_resend_s:
            self._send_hello()  # ours or its answer was lost: without it the session stays half up
        if now_s >= self._next_tick_s and self.link_up:
            self._next_tick_s = now_s + self.config.period_s
            uptime_ms = int((now_s - self._start_s) * 1000) & 0xFFFFFFFF
            rx = self.decoder.stats
            self.send(m.Heartbeat(uptime_ms=uptime_ms, mode=0, battery_mv=0, rx_frames=rx.frames & 0xFFFFFFFF,
                                  rx_rejects=rx.rejects & 0xFFFFFFFF, rx_lost=rx.lost & 0xFFFFFFFF,
                                  log_first_sample=0, log_next_sample=0, episode=0, signing_rejects=0))
            self.send(m.Timesync(origin_us=time.time_ns() // 1000, receive_us=0, transmit_us=0))
            self._emit_stats()
        self._retransmit(now_s)
        if self._finish_requested and self._finished_at is None:
            self._finished_at = self.backfill.finish_at()
        if self._retry_backfill_now:  # the run's final backfill: every range again, now
            self._retry_backfill_now = False
            self.backfill.retry_now()
            self._next_backfill_s = 0.0
            self._publish_backfill()
        if now_s >= self._next_backfill_view_s:
            self._next_backfill_view_s = now_s + 0.1
            self._publish_backfill()
        if self.link_up and now_s >= self._next_backfill_s:
            self._next_backfill_s = now_s + 0.5
            if self.config.backfill:
                for start, end in self.backfill.due(now_s):
                    self.send(m.LogRequest(first_sample=start, end_sample=end), wait=False)
            self._rerequest_dump_chunks(now_s)

    def _retransmit(self, now_s: float) -> None:
        for pending in self._pending.late(now_s):
            if pending.attempts > self.config.retries and (pending.give_up_s is None or now_s >= pending.give_up_s):
                self._pending.discard(pending.seq)
                pending.done.set()
                continue
            pending.attempts += 1
            pending.deadline_s = now_s + self._ack_timeout_s()
            with self._send_lock:  # the same seq (re-signed if signing): the agent ACKs again without re-executing
                pending.wire = self.encoder.retry(pending.wire)
                self._write(pending.message, pending.seq, pending.wire, retry=True)

    def _publish_backfill(self) -> None:
        """What request_backfill() waits on, computed here on the reader thread that owns the planner."""
        with self._cond:
            self._backfill_view = (self.backfill.pending(), len(self.backfill.held),
                                   sum(b - a for a, b in self.backfill.missing()))
            self._cond.notify_all()

    def _rerequest_dump_chunks(self, now_s: float) -> None:
        for kind, dump_id, start, end in self.dumps.due_rerequests(now_s):
            self.send(m.DumpRequest(kind=kind, dump_id=dump_id, offset=start, length=end - start), wait=False)

    # ------------------------------------------------------------------ frames in
    def _handle(self, frame: Frame, host_ns: int) -> None:
        if self._recent.seen(frame.inner):
            return  # the same frame twice (same seq, same bytes): handled and recorded once
        msg = frame.message
        backfilled = bool(frame.flags & FrameFlag.REPLAYED)
        deliver = True
        if isinstance(msg, m.Sample):
            if not self.sample_check.possible(msg.sample, msg.t_us):
                self._impossible_sample(msg)
                return
            self.backfill.episodes.saw_sample(msg.sample, msg.episode, msg.mode == Mode.LEARNING)
            new = self.backfill.held.add(msg.sample)
            deliver = new  # a sample already held (live and replayed both came) is recorded once
            if backfilled and new:
                self.stats.backfilled += 1
        elif isinstance(msg, _SEQUENCED):
            (self.backfill.episodes.starts if isinstance(msg, m.EpisodeStart) else self.backfill.episodes.ends).add(
                msg.episode)
            key = (msg.MSG_ID, msg.episode, msg.sample)
            deliver = key not in self._episodes_seen
            self._episodes_seen.add(key)
            if backfilled and deliver:
                self.stats.backfilled += 1
        elif isinstance(msg, m.Ack):
            self._on_ack(msg)
        elif isinstance(msg, m.Hello):
            self._on_hello(msg)
            if self.failure is not None:
                return  # another agent: nothing of it reaches the recording
        elif isinstance(msg, m.Heartbeat):
            self.last_heartbeat = msg
            self.backfill.saw_log_window(msg.log_first_sample, msg.log_next_sample)
            self.sample_check.heartbeat(msg.log_next_sample, msg.uptime_ms)
        elif isinstance(msg, m.Timesync):
            self._on_timesync(msg, host_ns)
        elif isinstance(msg, m.ParamValue):
            with self._cond:
                self._expected_params = msg.count
                self.params.update(Parameter.from_message(msg))
                self.dumps.assembler.saw_parameter(msg.name, msg.value)  # the grid bounds a dump's size
                self._param_updates += 1
                self._cond.notify_all()
        elif isinstance(msg, m.DumpChunk):
            with self._cond:
                if self.dumps.feed(msg, time.monotonic()) is not None:
                    self._cond.notify_all()
        elif isinstance(msg, m.LogRange):
            self._log_ranges += 1
            self.backfill.saw_log_window(msg.first_sample, msg.next_sample)
            self._emit(LinkEvent(EventKind.BACKFILL_DONE, host_ns, f"{msg.replayed} frames replayed",
                                 msg.to_dict()))
        if isinstance(msg, _WAITED_FOR):
            with self._cond:
                self._cond.notify_all()
        # The run is over: what the agent sends from after its end is recorded raw only (the decoded recording ends
        # with the run and the final backfill completes it; the raw frames keep the link's record exact).
        after_end = self._finished_at is not None and getattr(msg, "sample", self._finished_at) >= self._finished_at
        if deliver and self.agent_hello is not None:  # nothing reaches listeners from an incompatible peer
            t_us = getattr(msg, "t_us", None)
            agent_ns = self.clock.to_host_ns(t_us) if isinstance(t_us, int) and t_us else None
            received = Received(frame, host_ns, agent_ns, backfilled, after_end)
            self.listeners.received(received)

    def _on_ack(self, ack: m.Ack) -> None:
        pending = self._pending.acknowledge(ack)
        if pending is None:
            return
        if pending.attempts == 1:  # Karn: a retried command's RTT is ambiguous
            self.stats.round_trip(time.monotonic() - pending.first_sent_s)
        with self._cond:
            self._cond.notify_all()

    def _on_hello(self, hello: m.Hello) -> None:
        self._hello_resend_s = None
        problem = incompatibility(hello)
        previous = self.agent_hello
        if problem is None and previous is not None and previous.node_id != hello.node_id:
            self._another_agent(previous, hello)
            return
        with self._cond:
            if problem is not None:
                self._hello_problem = problem
            else:
                self.agent_hello = hello
            self._cond.notify_all()
        if problem is not None or previous is None:
            return
        if previous.boot_id != hello.boot_id:
            # The agent rebooted: sequence, clock and sample indices restart.
            self.decoder.reset_sequence()
            self.clock.reset()
            self.backfill.reset()
            self.sample_check.reset()
            self._episodes_seen.clear()
            self._emit(LinkEvent(EventKind.RESYNCED, time.time_ns(), "the agent rebooted", self._hello_data()))
        if self._restoring:
            self._restoring = False
            self.link_up = True
            self._next_backfill_s = time.monotonic() + 0.3  # let a heartbeat announce the log window first
            # Ask for every hole again at once: the link may be up only briefly (a radio near the surface), and
            # waits grown while it was down would skip the whole window while the on-board log turns over.
            self.backfill.retry_now()
            self._emit(LinkEvent(EventKind.LINK_RESTORED, time.time_ns(), self.link.url, self._hello_data()))

    def _impossible_sample(self, msg: m.Sample) -> None:
        count = self.sample_check.impossible
        if count == 1 or count % 1000 == 0:  # said, not repeated for every one of a stream of them
            beat = self.last_heartbeat
            why = (f"SAMPLE index {msg.sample} cannot be true (the agent's log ends at "
                   f"{beat.log_next_sample if beat else '?'}); ignored ({count} so far)")
            self._emit(LinkEvent(EventKind.ERROR, time.time_ns(), why, {"sample": msg.sample, "ignored": count}))

    def _another_agent(self, previous: m.Hello, hello: m.Hello) -> None:
        """Another node id answered after a reconnect (every ESP8266 access point is 192.168.4.1): not a reboot
        of our agent. Nothing from it is recorded or commanded; the session stops and says why."""
        why = (f"{self.link.url}: another agent answered after the reconnect (id {hello.node_id:08x} "
               f"{one_line(hello.name)!r}, was {previous.node_id:08x} {one_line(previous.name)!r}); stopping")
        self.failure = AgentChangedError(why)
        self._emit(LinkEvent(EventKind.ERROR, time.time_ns(), why, hello.to_dict()))
        self._stop.set()
        self.link_up = False
        self._pending.release_all()
        self.link.drop()
        with self._cond:
            self._cond.notify_all()

    def _on_timesync(self, msg: m.Timesync, host_ns: int) -> None:
        if msg.receive_us == 0 and msg.transmit_us == 0:  # a request from the agent: answer at once
            now_us = time.time_ns() // 1000
            self.send(m.Timesync(origin_us=msg.origin_us, receive_us=host_ns // 1000, transmit_us=now_us))
            return
        sample = self.clock.add(msg.origin_us, msg.receive_us, msg.transmit_us, host_ns // 1000)
        self.stats.round_trip(max(0.0, sample.round_trip_us) / 1e6)

    # ------------------------------------------------------------------ helpers
    def _ack_timeout_s(self) -> float:
        rtt = self.stats.rtt_median_s()
        return max(self.config.ack_timeout_s, 3 * rtt) if rtt is not None else self.config.ack_timeout_s

    def _send_hello(self) -> None:
        self._hello_resend_s = time.monotonic() + HELLO_RESEND_S
        self.send(ground_hello(self.config.node_id, self._boot_id))

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

    def rx_listener(self, callback: Callable[[Received], None]) -> SessionListener:
        """A listener that only wants received frames (for progress displays)."""
        return ReceivedCallback(callback)
