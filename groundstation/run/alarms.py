"""The run's alarms: low battery, a link lost too long, the depth and dive-time limits, an agent gone silent.

Each alarm is said once when its condition starts (printed by the run, recorded as an `alarm` event on /event,
shown in the view's event log) and again only after the condition has cleared.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

from groundstation.run.alarm_limits import DEPTH_LIMIT_M, LINK_LOST_S
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import Mode
from protocol import messages as m

if TYPE_CHECKING:  # `dive --help` reads the defaults below without loading the session
    from groundstation.session.agent_session import Session


@dataclass(frozen=True, slots=True)
class AlarmConfig:
    battery_margin_v: float = 0.1  # alarm this far above the voltage at which the agent surfaces (low_batt_v)
    link_lost_s: float = LINK_LOST_S  # the link down this long
    silent_s: float = LINK_LOST_S  # no frame from the agent this long
    depth_m: float = DEPTH_LIMIT_M  # deeper than this
    dive_time_fraction: float = 0.9  # of the agent's max_dive_s since it left IDLE


class Alarms:
    """A session listener; `check()` (the run's loop, a few times a second) looks at what needs a clock."""

    def __init__(self, session: Session, say: Callable[[str], None], config: AlarmConfig | None = None) -> None:
        self.session, self.say, self.config = session, say, config or AlarmConfig()
        self.raised: list[str] = []  # every alarm said, in order (for the run's summary and the tests)
        self._active: set[str] = set()
        self._lock = threading.Lock()
        self._last_rx_s = time.monotonic()
        self._lost_since: float | None = None
        self._left_idle_ms: int | None = None  # the agent's uptime when it left IDLE

    def _param(self, name: str) -> float | None:
        return self.session.params.get(name).value if name in self.session.params else None

    def _set(self, key: str, active: bool, text: str) -> None:
        with self._lock:
            if not active:
                self._active.discard(key)
                return
            if key in self._active:
                return
            self._active.add(key)
            self.raised.append(text)
        self.say(f"ALARM: {text}")
        self.session.listeners.event(LinkEvent(EventKind.ALARM, time.time_ns(), text, {"alarm": key}))

    # ------------------------------------------------------------------ listener (the session's reader thread)
    def on_received(self, received: Received) -> None:
        self._last_rx_s = time.monotonic()
        if received.backfilled or received.after_end:
            return  # old news: an alarm is about now
        message = received.message
        if isinstance(message, m.Heartbeat):
            self._heartbeat(message)
        elif isinstance(message, m.Sample):
            limit = self.config.depth_m
            self._set("depth", message.depth_m > limit,
                      f"depth {message.depth_m:.2f} m is past the {limit:g} m limit")

    def _heartbeat(self, beat: m.Heartbeat) -> None:
        low = self._param("low_batt_v")
        if low is not None and beat.battery_mv:
            volts, alarm_v = beat.battery_mv / 1000, low + self.config.battery_margin_v
            self._set("battery", volts < alarm_v,
                      f"battery low: {volts:.2f} V (the agent surfaces below {low:.2f} V, low_batt_v)")
        if beat.mode in (Mode.IDLE, Mode.SURFACING):
            self._left_idle_ms = None
            self._set("dive_time", False, "")
            return
        if self._left_idle_ms is None:
            self._left_idle_ms = beat.uptime_ms
        limit_s = self._param("max_dive_s")
        if limit_s:
            dived_s = (beat.uptime_ms - self._left_idle_ms) / 1000
            self._set("dive_time", dived_s >= self.config.dive_time_fraction * limit_s,
                      f"dive time {dived_s:.0f} s of the agent's {limit_s:g} s limit (max_dive_s): it surfaces at "
                      "the limit")

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.LINK_LOST:
            self._lost_since = self._lost_since or time.monotonic()
        elif event.kind in (EventKind.LINK_RESTORED, EventKind.CONNECTED, EventKind.RESYNCED):
            self._lost_since = None

    # ------------------------------------------------------------------ the clock's alarms
    def check(self, now_s: float | None = None) -> None:
        now_s = time.monotonic() if now_s is None else now_s
        lost_s = now_s - self._lost_since if self._lost_since is not None else 0.0
        self._set("link_lost", lost_s > self.config.link_lost_s,
                  f"link lost for more than {self.config.link_lost_s:g} s")
        silent_s = now_s - self._last_rx_s
        self._set("silent", silent_s > self.config.silent_s,
                  f"the agent stopped sending: nothing from it for {silent_s:.0f} s")
