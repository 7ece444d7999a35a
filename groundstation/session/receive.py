"""A session's reader thread: receive, decode, handle each frame, and the timers (heartbeat, retries, backfill)."""

from __future__ import annotations

import time

from groundstation.errors import AgentChangedError, HubDroppedError, LinkError, LinkTakenError
from groundstation.links.hub_events import DROPPED, GROUND_FLAG, TOOL_KINDS, parse_ground_text
from groundstation.safe_output import one_line
from groundstation.session.clock import timesync_problem
from groundstation.session.core import HELLO_TRIES, SessionCore
from groundstation.session.events import EventKind, LinkEvent, Received
from groundstation.session.hello import incompatibility
from groundstation.session.params import Parameter
from protocol import Frame, FrameFlag, Mode, StreamDecoder
from protocol import messages as m
from protocol.enums import LINK_TAKEN_TEXT

_SEQUENCED = (m.EpisodeStart, m.EpisodeEnd)
_WAITED_FOR = (m.Sample, m.LogRange, m.EpisodeStart, m.EpisodeEnd)  # what request_backfill's waiter looks at


class ReceiveLoop(SessionCore):
    """The reader thread's side of a Session: it never dies; transport errors become LinkEvents and reconnects."""

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
        self._hello_tries = 0
        self._send_hello()

    def _tick(self, now_s: float) -> None:
        if self.agent_hello is not None and now_s - self._last_rx_s > self.config.link_timeout_s:
            raise LinkError(f"no frame from the agent for {self.config.link_timeout_s:g} s")
        if self._hello_resend_s is not None and now_s >= self._hello_resend_s:
            if self._restoring and self._hello_tries >= HELLO_TRIES:  # frames come, answers never: a new connection
                raise LinkError(f"no answer to {self._hello_tries} HELLOs on this connection; reconnecting")
            self._send_hello()  # ours or its answer was lost: without it the session stays half up
        if now_s >= self._next_tick_s and self.link_up:
            self._next_tick_s = now_s + self.config.period_s
            uptime_ms = int((now_s - self._start_s) * 1000) & 0xFFFFFFFF
            rx = self.decoder.stats
            self.send(m.Heartbeat(uptime_ms=uptime_ms, mode=0, battery_mv=0, rx_frames=rx.frames & 0xFFFFFFFF,
                                  rx_rejects=rx.rejects & 0xFFFFFFFF, rx_lost=rx.lost & 0xFFFFFFFF,
                                  log_first_sample=0, log_next_sample=0, episode=0, signing_rejects=0))
            origin_us = time.time_ns() // 1000
            self._timesync_origins.append(origin_us)
            self.send(m.Timesync(origin_us=origin_us, receive_us=0, transmit_us=0))
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
                # ... unless a session started since a try left: its ACK memory is empty (SPEC.md s. 5)
                if 0 <= pending.written_in != self._session_starts:
                    pending.crossed = True
                self._write(pending.message, pending.seq, pending.wire, retry=True)
                pending.written_in = self._session_starts

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
        backfilled = bool(frame.flags & FrameFlag.REPLAYED)
        if self._recent.seen(frame.inner):
            self._unused(frame, host_ns, backfilled)
            return  # the same frame twice (same seq, same bytes): handled and recorded once
        msg = frame.message
        deliver = True
        if isinstance(msg, m.Sample):
            if not self.sample_check.possible(msg.sample, msg.t_us):
                self._impossible_sample(msg)
                self._unused(frame, host_ns, backfilled)
                return
            self.backfill.episodes.saw_sample(msg.sample, msg.episode, msg.mode == Mode.LEARNING)
            new = self.backfill.held.add(msg.sample)
            deliver = new  # a sample already held (live and replayed both came) is recorded once
            if backfilled and new:
                self.stats.backfilled += 1
            if not backfilled:
                self._saw_mode(msg.mode)
        elif isinstance(msg, _SEQUENCED):
            if not backfilled:
                self.backfill.episodes.saw_generation(msg.generation)
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
            self._program_up.set()
        elif isinstance(msg, m.Heartbeat):
            self.last_heartbeat = msg
            if msg.uptime_ms > 0:
                self._program_up.set()
            self.backfill.episodes.saw_generation(msg.generation)
            self._saw_mode(msg.mode)
            self.backfill.saw_log_window(msg.log_first_sample, msg.log_next_sample)
            # what the planner believes of the claim, not the claim: a next index near 2^32 must not make every
            # index below it possible. Not known_end: the run's end caps that, and the true SAMPLEs the agent sends
            # after it would be refused as impossible, unrecorded though their seq gaps were counted
            self.sample_check.heartbeat(self.backfill.believed_end(msg.log_next_sample), msg.uptime_ms)
        elif isinstance(msg, m.Timesync):
            self._on_timesync(msg, host_ns)
        elif isinstance(msg, m.Text) and msg.text == LINK_TAKEN_TEXT and not backfilled:
            self._link_taken()
        elif isinstance(msg, m.Text) and frame.flags & GROUND_FLAG and self.link.url.startswith("hub://"):
            event = parse_ground_text(msg.text, TOOL_KINDS)  # the run's marker or alarm (links/hub_events.py)
            if event is not None and event[0] == DROPPED:
                self._give_up(HubDroppedError(f"{self.link.url}: {event[1]}"))  # the hub closes this link next
                return
            if event is not None:  # its event here too
                self._emit(LinkEvent(EventKind(event[0]), host_ns, event[1], event[2]))
                return
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
        else:
            self._unused(frame, host_ns, backfilled)

    def _unused(self, frame: Frame, host_ns: int, backfilled: bool) -> None:
        """A frame decoded (its seq counted) but not used: a replay of a sample already held (a LOG_REQUEST range
        holds them between its holes), an impossible SAMPLE, the same frame twice, or one that came before the
        agent's first HELLO (its HELLO on connecting lost: the frames before the answer to ours, whose seq gaps the
        loss count saw too). Its raw bytes still go to the recorder, so that the recording keeps every frame whose
        seq the loss count saw; the recorder writes those from before the HELLO only once a compatible one came."""
        self.listeners.unused(Received(frame, host_ns, None, backfilled))

    def _saw_mode(self, mode: int) -> None:
        # no lock and no notify on this hot path (every SAMPLE): the rare waiter polls (SessionCore._mode_after)
        self.agent_mode = mode
        self._mode_updates += 1

    def _on_ack(self, ack: m.Ack) -> None:
        pending = self._pending.acknowledge(ack, self._mode_updates)
        if pending is None:
            return
        rtt_s = time.monotonic() - pending.first_sent_s
        # Hand the GIL to the thread waiting for this ACK now: it would otherwise wait until this reader blocks
        # again, after the rest of the read (the replies behind the ACK) and the timers (groundstation_bench:
        # command round trip 163 -> 140 us median against a 58-61 us echo). The statistic is kept after.
        time.sleep(0)
        if pending.attempts == 1:  # Karn: a retried command's RTT is ambiguous
            self.stats.round_trip(rtt_s)
        with self._cond:
            self._cond.notify_all()

    def _on_hello(self, hello: m.Hello) -> None:
        self._hello_resend_s = None
        self._hello_tries = 0
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

    def _link_taken(self) -> None:
        """Another ground's connection replaced ours (the agent has one link): stop rather than take it back, which
        would only have the two fight over it (issue 25 H4); say so in one line."""
        why = (f"{self.link.url}: the agent's link was taken by another ground (another dive run or tool, here or on "
               "another machine); stopping rather than take it back")
        self._give_up(LinkTakenError(why))

    def _give_up(self, failure: LinkError) -> None:
        """Stop the session by itself: nothing more is sent or recorded; `failure` says why."""
        self.failure = failure
        self._emit(LinkEvent(EventKind.ERROR, time.time_ns(), str(failure)))
        self._stop.set()
        self.link_up = False
        self._pending.release_all()
        self.link.drop()
        with self._cond:
            self._cond.notify_all()

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
        host_us = host_ns // 1000
        if msg.receive_us == 0 and msg.origin_us in self._timesync_origins:
            # A starting agent's clock reads 0 until its program runs (SPEC s. 4, a starting agent): no measurement
            self._timesync_origins.remove(msg.origin_us)
            return
        problem = "not an answer to a TIMESYNC we sent" if msg.origin_us not in self._timesync_origins \
            else timesync_problem(msg.origin_us, msg.receive_us, msg.transmit_us, host_us)
        if problem is not None:  # ignored and counted: one such frame must not move every recorded time
            self.stats.timesyncs_ignored += 1
            if self.stats.timesyncs_ignored == 1 or self.stats.timesyncs_ignored % 1000 == 0:
                self._emit(LinkEvent(EventKind.ERROR, time.time_ns(),
                                     f"TIMESYNC ignored: {problem} ({self.stats.timesyncs_ignored} so far)",
                                     {"ignored": self.stats.timesyncs_ignored}))
            return
        self._timesync_origins.remove(msg.origin_us)  # each request is answered once
        sample = self.clock.add(msg.origin_us, msg.receive_us, msg.transmit_us, host_us)
        self.stats.round_trip(max(0.0, sample.round_trip_us) / 1e6)
