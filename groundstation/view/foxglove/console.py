"""Foxglove as a console (issue 40): the agent's log and the run's events as foxglove.Log, the parameters' metadata,
and log times on the agent's clock.

- `/log` (schema foxglove.Log, JSON): the agent's TEXT lines (name "agent") and the run's events (alarms, their
  clearing and acknowledgement, markers, tools' commands, link losses; name "dive"), so Foxglove's Log panel lists
  them all, none overwritten by the next (the events panel showed only the newest);
- `/parameters/info`: one message per parameter as the agent reports it, with its unit, range, whether a change
  resets learning and what it is (`dive params`'s columns): the Parameters panel shows names and values only;
- log times: a message with an agent time gets that time mapped to the host clock (the session's clock sync), as
  PlotJuggler and Foxglove plot on one time: SAMPLEs that arrive in one batch no longer share one stamp.
"""

from __future__ import annotations

import json
from typing import Any

from groundstation.session.events import EventKind, LinkEvent
from protocol import messages as m
from protocol.parameters import BY_NAME

LOG_TOPIC = "/log"
LOG_SCHEMA_NAME = "foxglove.Log"
# foxglove.Log as JSON Schema (https://docs.foxglove.dev/docs/visualization/message-schemas/log)
LOG_SCHEMA: dict[str, Any] = {
    "title": "foxglove.Log", "description": "A log message", "type": "object",
    "properties": {
        "timestamp": {"type": "object", "title": "time", "properties": {
            "sec": {"type": "integer", "minimum": 0}, "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
        "level": {"type": "integer", "description": "0 unknown, 1 debug, 2 info, 3 warning, 4 error, 5 fatal"},
        "message": {"type": "string"}, "name": {"type": "string"}, "file": {"type": "string"},
        "line": {"type": "integer", "minimum": 0}}}
_AGENT_LEVELS = {0: 1, 1: 2, 2: 3, 3: 4}  # TEXT's Severity (debug, info, warning, error) -> foxglove.Log level
_EVENT_LEVELS = {EventKind.ALARM: 4, EventKind.LINK_LOST: 3, EventKind.ERROR: 3}  # the rest info (2)
NOT_LOGGED = frozenset((EventKind.STATS,))  # 1 Hz statistics: plotted on /link, not lines to read

PARAMETER_INFO_TOPIC = "/parameters/info"
PARAMETER_INFO_SCHEMA_NAME = "diving_agent.parameter_info"
PARAMETER_INFO_SCHEMA: dict[str, Any] = {
    "title": "diving_agent.parameter_info", "type": "object",
    "properties": {
        "name": {"type": "string"}, "value": {"type": "number"}, "unit": {"type": "string"},
        "minimum": {"type": "number"}, "maximum": {"type": "number"},
        "resets_learning": {"type": "boolean", "description": "a change restarts the learner (it forgets)"},
        "refused_in": {"type": "array", "items": {"type": "string"}, "description": "modes a change is refused in"},
        "description": {"type": "string"}}}


def log_body(time_ns: int, level: int, message: str, name: str) -> bytes:
    return json.dumps({"timestamp": {"sec": time_ns // 1_000_000_000, "nsec": time_ns % 1_000_000_000},
                       "level": level, "message": message, "name": name, "file": "", "line": 0}).encode()


def agent_log(text: m.Text, time_ns: int) -> bytes:
    """An agent's TEXT line as foxglove.Log."""
    return log_body(time_ns, _AGENT_LEVELS.get(text.severity, 0), text.text, "agent")


def event_log(event: LinkEvent) -> bytes | None:
    """The run's event as foxglove.Log ("alarm: depth 1.31 m is past the 1.2 m limit"); None for statistics."""
    if event.kind in NOT_LOGGED:
        return None
    text = f"{event.kind}: {event.detail}" if event.detail else str(event.kind)
    return log_body(event.host_time_ns, _EVENT_LEVELS.get(event.kind, 2), text, "dive")


def parameter_info(value: m.ParamValue) -> bytes:
    """A PARAM_VALUE with what `dive params` says of it."""
    definition = BY_NAME.get(value.name)
    return json.dumps({
        "name": value.name, "value": value.value, "minimum": value.minimum, "maximum": value.maximum,
        "unit": definition.unit if definition is not None else "",
        "resets_learning": bool(definition is not None and definition.learner),
        "refused_in": [mode.name for mode in definition.refused_in] if definition is not None else [],
        "description": definition.doc if definition is not None else "(not in this ground station's table)",
    }).encode()


class LogTimes:
    """Per topic, the log time of each message: its agent time on the host clock when the session knows the
    mapping (and it is within a minute of the host's: a wild clock must not scatter a plot), else the arrival time,
    nudged by 1 ns past the topic's last so that a batch's messages keep their order and never share a stamp."""

    TRUSTED_NS = 60_000_000_000

    def __init__(self) -> None:
        self._last: dict[str, int] = {}

    def of(self, topic: str, host_ns: int, agent_ns: int | None) -> int:
        if agent_ns is not None and abs(agent_ns - host_ns) < self.TRUSTED_NS:
            self._last[topic] = max(self._last.get(topic, 0), agent_ns)
            return agent_ns
        last = self._last.get(topic, 0)
        log_ns = host_ns if host_ns > last else last + 1
        self._last[topic] = log_ns
        return log_ns
