"""A session with one agent: HELLO, heartbeats, TIMESYNC, commands with ACK and retry, params, dumps, backfill.

One reader thread owns the link's receive side and every timer; it never dies: transport errors become
LinkEvents (link lost / restored / resynced) and it reconnects with backoff; a listener's exception is
caught and reported as an ERROR event. Commands may be sent from any thread except listeners' callbacks
(their ACK arrives on the reader thread); send(..., wait=False) is the form for those.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from groundstation.errors import CommandError, CommandTimeout, IncompatibleAgentError, LinkTimeout, ParameterError
from groundstation.session.core import SessionConfig
from groundstation.session.dumps import Dump
from groundstation.session.events import EventKind, LinkEvent, Received, ReceivedCallback, SessionListener
from groundstation.session.params import Parameter, ParamTable, load_cached, parse_value, save_cached
from groundstation.session.receive import ReceiveLoop
from protocol import DumpKind, Message
from protocol import messages as m

__all__ = ["Session", "SessionConfig"]  # SessionConfig is imported from here


class Session(ReceiveLoop):
    """The public side: connect, close, commands and their waits (state: SessionCore; reader: ReceiveLoop)."""

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

    def mark(self, text: str, by: str = "") -> None:
        """A user marker: goes to every listener (the recorder writes it to /marker); `by`: the tool it came from."""
        self._emit(LinkEvent(EventKind.MARKER, time.time_ns(), text, {"text": text, **({"by": by} if by else {})}))

    # ------------------------------------------------------------------ commands
    def command(self, message: Message, timeout_s: float | None = None) -> m.Ack:
        ack = self.send(message, wait=True, timeout_s=timeout_s)
        assert ack is not None
        return ack

    def refresh_params(self, timeout_s: float = 3.0) -> ParamTable:
        """PARAM_LIST, wait for the whole table; fall back to the disk cache if the agent stays silent.

        A refusal (UNAUTHORIZED from a keyed agent: no key or a wrong one) is the agent's answer, not silence: it
        raises CommandError with the agent's reason (issue 26, D4), never a cached table that looks like success."""
        assert self.agent_hello is not None
        key = (self.agent_hello.definitions_hash, self.agent_hello.node_id)
        try:
            self.command(m.ParamListRequest())
            with self._cond:
                self._cond.wait_for(lambda: self._expected_params and len(self.params) >= self._expected_params,
                                    timeout_s)
        except CommandTimeout:
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

    def rx_listener(self, callback: Callable[[Received], None]) -> SessionListener:
        """A listener that only wants received frames (for progress displays)."""
        return ReceivedCallback(callback)
