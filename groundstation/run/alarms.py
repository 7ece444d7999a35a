"""The run's alarms: low battery, a link lost too long, the depth and dive-time limits, an agent gone silent.

Each alarm is said once when its condition starts (printed by the run, recorded as an `alarm` event on /event,
shown in the view's event log), and once more when it clears (an `alarm_cleared` event): past a hysteresis, so a
depth hovering at the limit is one alarm, not one a second. As in QGroundControl and MAVProxy, the alarm flag on the
status line stays until the operator acknowledges it (`dive ack`, the key `a` in the run pane, Foxglove's ack
service: an `alarm_ack` event), even after the condition cleared: an alarm that came and went while nobody looked
is still seen.

| state          | flag on the status line          | becomes                                      |
|----------------|----------------------------------|----------------------------------------------|
| quiet          | (none)                           | raised: the condition starts                 |
| raised         | ALARM depth                      | acked (ack), cleared-unacked (clears)        |
| cleared-unacked| ALARM depth (cleared)            | quiet (ack), raised (starts again)           |
| acked          | alarm depth (acked)              | quiet (clears)                               |
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
    depth_hysteresis_m: float = 0.05  # a depth alarm clears this far above the limit (a few sensor noise widths)
    battery_hysteresis_v: float = 0.02  # a battery alarm clears this far above its voltage (a sag under load)


def past(value: float, limit: float, decimals: int = 2) -> str:
    """`value` with as many decimals as it takes to read as past `limit`: never "1.20 m is past the 1.2 m limit"."""
    for places in range(decimals, 7):
        text = f"{value:.{places}f}"
        if float(text) != limit:
            return text
    return f"{value:.6f}"


class Alarms:
    """A session listener; `check()` (the run's loop, a few times a second) looks at what needs a clock."""

    def __init__(self, session: Session, say: Callable[[str], None], config: AlarmConfig | None = None) -> None:
        self.session, self.say, self.config = session, say, config or AlarmConfig()
        self.raised: list[str] = []  # every alarm said, in order (for the run's summary and the tests)
        self._active: set[str] = set()
        self._unacked: dict[str, None] = {}  # raised and not acknowledged yet, in the order raised
        self._lock = threading.Lock()
        self._last_rx_s = time.monotonic()
        self._lost_since: float | None = None
        self._left_idle_ms: int | None = None  # the agent's uptime when it left IDLE

    def _param(self, name: str) -> float | None:
        return self.session.params.get(name).value if name in self.session.params else None

    def _set(self, key: str, active: bool, text: str, cleared: bool | None = None, clear_text: str = "") -> None:
        """`active`: the condition holds; `cleared` (default: not active): it has ended past its hysteresis. Between
        the two (neither) an alarm raised stays raised and none is raised."""
        cleared = not active if cleared is None else cleared
        with self._lock:
            if cleared and key in self._active:
                self._active.discard(key)
                line = f"cleared: {clear_text or key}"
            elif active and key not in self._active:
                self._active.add(key)
                self._unacked[key] = None
                self.raised.append(text)
                line = ""
            else:
                return
        if line:
            self.say(line)
            self.session.listeners.event(LinkEvent(EventKind.ALARM_CLEARED, time.time_ns(), line, {"alarm": key}))
            return
        self.say(f"ALARM: {text}")
        self.session.listeners.event(LinkEvent(EventKind.ALARM, time.time_ns(), text, {"alarm": key}))

    def acknowledge(self, by: str) -> str:
        """The operator has seen the alarms: the flag goes (an active one shows as acked until it clears). The line
        that says what was acknowledged, also recorded as an `alarm_ack` event."""
        with self._lock:
            seen = list(self._unacked)
            self._unacked.clear()
            active = set(self._active)
        if not seen:
            return f"no alarm to acknowledge ({by})"
        what = ", ".join(f"{key} ({'active' if key in active else 'cleared'})" for key in seen)
        line = f"alarms acknowledged by {by}: {what}"
        self.session.listeners.event(LinkEvent(EventKind.ALARM_ACK, time.time_ns(), line, {"alarms": seen, "by": by}))
        return line

    def flag(self) -> str:
        """The status line's alarm field: `ALARM depth, battery (cleared)` until acknowledged, `alarm depth (acked)`
        while an acknowledged one lasts, "" when all is quiet."""
        with self._lock:
            unacked = [key if key in self._active else f"{key} (cleared)" for key in self._unacked]
            acked = [key for key in self._active if key not in self._unacked]
        if unacked:
            return "ALARM " + ", ".join(unacked)
        return f"alarm {', '.join(sorted(acked))} (acked)" if acked else ""

    # ------------------------------------------------------------------ listener (the session's reader thread)
    def on_received(self, received: Received) -> None:
        self._last_rx_s = time.monotonic()
        if received.backfilled or received.after_end:
            return  # old news: an alarm is about now
        message = received.message
        if isinstance(message, m.Heartbeat):
            self._heartbeat(message)
        elif isinstance(message, m.Sample):
            limit, depth = self.config.depth_m, message.depth_m
            self._set("depth", depth > limit, f"depth {past(depth, limit)} m is past the {limit:g} m limit",
                      cleared=depth < limit - self.config.depth_hysteresis_m,
                      clear_text=f"depth {depth:.2f} m, back above the {limit:g} m limit")

    def _heartbeat(self, beat: m.Heartbeat) -> None:
        low = self._param("low_batt_v")
        if low is not None and beat.battery_mv:
            volts, alarm_v = beat.battery_mv / 1000, low + self.config.battery_margin_v
            self._set("battery", volts < alarm_v,
                      f"battery low: {volts:.2f} V (the agent surfaces below {low:.2f} V, low_batt_v)",
                      cleared=volts >= alarm_v + self.config.battery_hysteresis_v,
                      clear_text=f"battery {volts:.2f} V")
        if beat.mode in (Mode.IDLE, Mode.SURFACING):
            self._left_idle_ms = None
            self._set("dive_time", False, "", clear_text=f"dive time: the agent is {Mode(beat.mode).name}")
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
                  f"link lost for more than {self.config.link_lost_s:g} s", clear_text="link restored")
        silent_s = now_s - self._last_rx_s
        self._set("silent", silent_s > self.config.silent_s,
                  f"the agent stopped sending: nothing from it for {silent_s:.0f} s",
                  clear_text="the agent is sending again")
