"""Ground events on a hub link: a run's markers and alarms, fanned out to its tools as TEXT frames with a ground flag.

A marker (`dive mark`) and an alarm (run/alarms.py) happen on the ground, not on the agent, so the agent's frames a
hub fans out never carry them; a `dive record` or `dive view` attached to the run would miss them. The hub sends
each as a TEXT frame of its own with flag bit 3 set, a bit the agent's protocol leaves free for receivers to ignore
(SPEC.md: bits 0-3) and that the hub clears on every agent frame it re-frames, so no agent can forge one: a tool
seeing it on a hub:// link turns the TEXT back into the run's event (session/receive.py), recorded and shown as
the run's own recorder and view do.

    text = kind US data-as-JSON US detail        (US = 0x1F; the detail cut to fit TEXT's 238 bytes)
"""

from __future__ import annotations

import json
import time
from typing import Any

from protocol import messages as m

GROUND_FLAG = 0x08  # flags bit 3: a frame the hub itself says (never set on a frame from the agent)
# the ground's event kinds its tools get (not its link's own events)
FANNED_OUT = frozenset(("marker", "alarm", "alarm_cleared", "alarm_ack", "command"))
DROPPED = "dropped"  # the hub's last word to one tool it drops for falling behind (run/hub_outbox.py), never fanned out
TOOL_KINDS = FANNED_OUT | {DROPPED}  # the ground TEXTs a tool's session reads from its hub
ACK_REQUEST = "ack"  # a tool's ground-flagged TEXT to its run's hub: acknowledge the alarms (dive ack)
ACK_ANSWERS = ("alarms acknowledged by ", "no alarm to acknowledge")  # how the hub's TEXT answer to it begins
TEXT_BYTES = 238  # TEXT's tail (protocol/messages.py)
_SEPARATOR = "\x1f"
_SEVERITY = {"alarm": 3}  # error; anything else info


def ground_text(kind: str, detail: str, data: dict[str, Any]) -> m.Text:
    """The TEXT that carries one of the run's events to its tools."""
    if kind == "marker" and data.get("text") == detail:
        # the marker's text is its detail: not sent twice (parse_ground_text puts it back)
        data = {k: v for k, v in data.items() if k != "text"}
    head = f"{kind}{_SEPARATOR}{json.dumps(data, separators=(',', ':'))}{_SEPARATOR}"
    room = TEXT_BYTES - len(head.encode())
    body = detail.encode()[:max(0, room)].decode(errors="ignore")  # cut on a character, never inside one
    return m.Text(t_us=time.time_ns() // 1000, severity=_SEVERITY.get(kind, 1), text=head + body)


def dropped_text(behind: int) -> m.Text:
    """Why the hub drops a tool: it fell `behind` frames behind. The tool's session stops with this as its line."""
    return ground_text(DROPPED, f"the run's hub dropped this tool: it fell {behind} frames behind reading them (the "
                       "tool or its machine too slow); the run goes on, attach again to follow it", {"behind": behind})


def parse_ground_text(text: str, kinds: frozenset[str] | tuple[str, ...] = FANNED_OUT,
                      ) -> tuple[str, str, dict[str, Any]] | None:
    """(kind, detail, data) of a ground TEXT of one of `kinds`; None for one that is not of this form (it is then an
    agent's line)."""
    parts = text.split(_SEPARATOR, 2)
    if len(parts) != 3 or parts[0] not in kinds:
        return None
    kind, encoded, detail = parts
    try:
        data = json.loads(encoded)
    except ValueError:
        return None
    if not isinstance(data, dict):
        return None
    if kind == "marker" and "text" not in data:
        data = {"text": detail, **data}
    return kind, detail, data
