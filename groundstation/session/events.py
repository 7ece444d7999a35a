"""What a session hands its listeners: received messages and link life-cycle events."""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, NamedTuple, Protocol

from groundstation.errors import ListenerError
from protocol import Frame, Message


class EventKind(StrEnum):
    CONNECTED = "connected"  # link up and HELLO exchanged
    LINK_LOST = "link_lost"  # no frame for the link timeout, or the transport failed
    LINK_RESTORED = "link_restored"  # reconnected after a loss
    RESYNCED = "resynced"  # the agent rebooted (new boot_id): sequence and clocks reset
    BACKFILL_DONE = "backfill_done"  # a LOG_REQUEST replay finished
    ERROR = "error"  # anything else worth showing; the session keeps running
    MARKER = "marker"  # a user marker (dive mark, or a key in the live run)
    STATS = "stats"  # 1 Hz link statistics (data: LinkStats.snapshot(), clock model)
    ALARM = "alarm"  # something the operator must see now (groundstation/run/alarms.py)
    ALARM_CLEARED = "alarm_cleared"  # an alarm's condition has ended (past its hysteresis)
    ALARM_ACK = "alarm_ack"  # the operator acknowledged the alarms (dive ack, a key in the run pane)
    COMMAND = "command"  # an operator's command from a tool through the run's hub, with its answer (run/hub.py)
    AGENT_BUSY = "agent_busy"  # a command answered BUSY, sent again soon (a virtual agent building its program)
    RUN_ENDED = "run_ended"  # the run a tool was attached to ended and closed its hub: not a link loss


class Received(NamedTuple):
    """One frame from the agent as the session saw it.

    A named tuple (immutable, as a frozen dataclass) because one is built for every frame received: a frozen
    dataclass's __init__ sets each field through object.__setattr__ and costs about 1 us more per frame.
    """

    frame: Frame
    host_time_ns: int  # host clock when the frame arrived
    agent_time_ns: int | None  # the message's agent time mapped to host time, when it has one
    backfilled: bool  # re-sent from the on-board log after a link outage
    after_end: bool = False  # came during the final backfill, from after the run's end: recorded raw only

    @property
    def message(self) -> Message:
        return self.frame.message


@dataclass(frozen=True, slots=True)
class Sent:
    """One frame the ground station sent (commands are recorded too)."""

    seq: int
    message: Message
    wire: bytes
    host_time_ns: int


@dataclass(frozen=True, slots=True)
class LinkEvent:
    kind: EventKind
    host_time_ns: int
    detail: str = ""
    data: dict[str, Any] = field(default_factory=dict)


class SessionListener(Protocol):
    """Anything that wants the session's traffic: the recorder, the live view, the progress display.

    Called from the session's reader thread; a listener must not block for long and must not raise (what it
    raises is caught: the listener is called no more, and `Listeners.failure` says why, for the run to stop on).
    """

    def on_received(self, received: Received) -> None: ...

    def on_sent(self, sent: Sent) -> None: ...

    def on_event(self, event: LinkEvent) -> None: ...


class Listeners:
    """The session's listeners, each told everything; what one raises becomes an ERROR event, never the session's."""

    def __init__(self, listeners: Iterable[SessionListener] = ()) -> None:
        self._listeners = list(listeners)
        # The first listener that raised, and why: a recorder that fails on every frame from then on must stop the
        # run with that reason, never leave it going on with a recording that silently stopped (issue 25 C2).
        self.failure: ListenerError | None = None

    def add(self, listener: SessionListener) -> None:
        self._listeners.append(listener)

    def received(self, received: Received) -> None:
        for listener in list(self._listeners):
            try:
                listener.on_received(received)
            except Exception as e:  # noqa: BLE001 a listener's bug must not stop the session
                self._failed(listener, e)

    def unused(self, received: Received) -> None:
        """A frame received but not used (already held, impossible, the same twice): only to the listeners that
        want those, through an optional `on_unused` (the recorder keeps their raw bytes)."""
        for listener in list(self._listeners):
            on_unused = getattr(listener, "on_unused", None)
            if on_unused is None:
                continue
            try:
                on_unused(received)
            except Exception as e:  # noqa: BLE001
                self._failed(listener, e)

    def sent(self, sent: Sent) -> None:
        for listener in list(self._listeners):
            try:
                listener.on_sent(sent)
            except Exception as e:  # noqa: BLE001
                self._failed(listener, e)

    def event(self, event: LinkEvent) -> None:
        for listener in list(self._listeners):
            try:
                listener.on_event(event)
            except Exception as e:  # noqa: BLE001
                if event.kind != EventKind.ERROR:  # reporting the failure of a report would loop
                    self._failed(listener, e)

    def _failed(self, listener: SessionListener, error: Exception) -> None:
        why = f"{type(listener).__name__} failed: {type(error).__name__}: {error}"
        with contextlib.suppress(ValueError):
            self._listeners.remove(listener)  # said once, never for each of the frames that follow
        if self.failure is None:
            self.failure = ListenerError(f"{why}; stopping the run")
        self.event(LinkEvent(EventKind.ERROR, time.time_ns(), why))


class ReceivedCallback:
    """A listener that only wants received frames (for progress displays)."""

    def __init__(self, callback: Callable[[Received], None]) -> None:
        self._callback = callback

    def on_received(self, received: Received) -> None:
        self._callback(received)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass
