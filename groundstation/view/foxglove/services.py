"""The operator's controls as Foxglove services: surface, hover, start, stop, pause, resume, target, mark, dump and
ack (the run's alarms acknowledged, as `dive ack`).

Each answers as its `dive` command does (session/control.py): the agent's ACK, the mode it ends in and the line the
command prints; a refusal is an answer too (`accepted` false, the line says why and what to do). What is not the
agent's answer (a bad request, no ACK at all, no agent attached) is a failed call with one line.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from typing import Any

from foxglove import MessageSchema, Schema, Service, ServiceRequest, ServiceSchema

from groundstation.errors import GroundStationError
from groundstation.links.hub_events import ACK_REQUEST, GROUND_FLAG, ground_text
from groundstation.session import control
from groundstation.session.agent_session import Session
from groundstation.view.foxglove.channels import MarkerWatch
from protocol import DumpKind
from protocol import messages as m
from protocol.errors import ProtocolError

MARK_WAIT_S = 3.0  # the run's hub confirms a marker once it is in the recording


class ServiceError(GroundStationError):
    """A call that got no answer from the agent: Foxglove shows `ServiceError: <the line>`."""


_OBJECT = {"$schema": "https://json-schema.org/draft/2020-12/schema", "type": "object"}
_ANSWER = {**_OBJECT, "title": "the agent's answer", "properties": {
    "command": {"type": "string"}, "accepted": {"type": "boolean"},
    "result": {"type": "string", "description": "the ACK's result (AckResult), NOT_SENT if the ground refused"},
    "reason": {"type": "string"}, "mode": {"type": "string", "description": "the mode after the command"},
    "message": {"type": "string", "description": "what the dive command prints"}}}
_DEPTH = {**_OBJECT, "required": ["depth_m"], "properties": {"depth_m": {"type": "number", "description": "[m]"}}}
REQUESTS: dict[str, dict[str, Any]] = {
    "surface": _OBJECT, "stop": _OBJECT, "pause": _OBJECT, "resume": _OBJECT,
    "start": {**_OBJECT, "properties": {"episodes": {
        "type": "integer", "minimum": 0, "description": "episodes of this start (0 = the max_episodes parameter)"}}},
    "hover": _DEPTH, "target": _DEPTH,
    "mark": {**_OBJECT, "required": ["text"], "properties": {"text": {"type": "string"}}},
    "dump": {**_OBJECT, "properties": {"kind": {"enum": ["values", "policy", "both"], "default": "both"}}},
    "ack": _OBJECT,
}


def _schema(name: str, schema: dict[str, Any]) -> MessageSchema:
    return MessageSchema(encoding="json", schema=Schema(name=f"diving_agent.{name}", encoding="jsonschema",
                                                        data=json.dumps(schema).encode()))


def _request(call: ServiceRequest) -> dict[str, Any]:
    """The request's JSON object (an empty payload is {}: Foxglove's button sends what the layout holds)."""
    if call.encoding != "json":
        raise ServiceError(f"{call.service_name}: requests are JSON, not {call.encoding!r}")
    if not call.payload.strip():
        return {}
    try:
        body = json.loads(call.payload)
    except (ValueError, RecursionError):
        raise ServiceError(f"{call.service_name}: the request is not JSON") from None
    if not isinstance(body, dict):
        raise ServiceError(f"{call.service_name}: the request must be a JSON object")
    return body


def _number(body: dict[str, Any], key: str, service: str) -> float:
    value = body.get(key)
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ServiceError(f"{service}: give {key} as a number, e.g. {{\"{key}\": 0.5}}")
    return float(value)


class Controls:
    """The services' handlers, each on the session the server is attached to (None until it is)."""

    def __init__(self, session: Callable[[], Session | None], markers: MarkerWatch,
                 warn: Callable[[str], None], is_owner: Callable[[int], bool] = lambda client_id: True) -> None:
        self._session = session
        self._markers = markers
        self._warn = warn
        self._is_owner = is_owner  # whether a client came through the door (live.py): nobody else commands

    def services(self) -> list[Service]:
        return [Service(name, handler=self._handler(name), schema=ServiceSchema(
            f"diving_agent.{name}", request=_schema(f"{name}_request", request),
            response=_schema("answer", _ANSWER))) for name, request in REQUESTS.items()]

    def _handler(self, name: str) -> Callable[[ServiceRequest], bytes]:
        act = getattr(self, f"_{name}")

        def handle(call: ServiceRequest) -> bytes:
            if not self._is_owner(call.client_id):
                raise ServiceError("not the run's owner")  # no warning in the owner's problems list either
            try:
                body = _request(call)
                s = self._session()
                if s is None:
                    raise ServiceError("not attached to the agent yet")
                answer: dict[str, Any] = act(s, body)
            except (GroundStationError, ProtocolError) as e:  # ProtocolError: a request that cannot be framed
                line = str(e)  # most already name the service ("target: give depth_m ..."): never twice
                self._warn(line if line.startswith(f"{name}:") else f"{name}: {line}")
                raise ServiceError(line) from None
            if answer.get("accepted") is False:
                self._warn(answer["message"])  # the refusal in Foxglove's problems list too
            return json.dumps(answer).encode()

        return handle

    # ------------------------------------------------------------------ one per service
    def _surface(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        return control.surface(s).as_dict()

    def _stop(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        return control.stop(s).as_dict()

    def _pause(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        return control.pause(s).as_dict()

    def _resume(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        return control.resume(s).as_dict()

    def _start(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        episodes = body.get("episodes", 0)
        if isinstance(episodes, bool) or not isinstance(episodes, int) or not 0 <= episodes < 2**32:
            raise ServiceError("start: episodes is a whole number from 0 (0 = the max_episodes parameter)")
        return control.start(s, episodes).as_dict()

    def _hover(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        return control.hover(s, _number(body, "depth_m", "hover")).as_dict()

    def _target(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        return control.target(s, _number(body, "depth_m", "target")).as_dict()

    def _mark(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        """A marker into the run's recording, through its hub (a link straight to an agent records nothing)."""
        text = body.get("text")
        if not isinstance(text, str) or not text.strip():
            raise ServiceError('mark: give the text, e.g. {"text": "tapped the tank"}')
        if not s.link.url.startswith("hub://"):
            raise ServiceError("mark: nothing records this link; attach to a run (dive view hub://RUN --foxglove)")
        confirmed = self._markers.confirmed
        confirmed.clear()
        s.send(m.Text(t_us=time.time_ns() // 1000, severity=1, text=text), wait=False)
        if not confirmed.wait(MARK_WAIT_S):
            raise ServiceError(f"mark: the run did not confirm the marker within {MARK_WAIT_S:g} s")
        return {"command": "mark", "accepted": True, "result": "ACCEPTED", "reason": "", "mode": control.mode_name(s),
                "message": f"marked in {s.link.url}"}

    def _ack(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        """The run's alarms acknowledged, as `dive ack` does: the flag on its status line goes (run/alarms.py)."""
        if not s.link.url.startswith("hub://"):
            raise ServiceError("ack: alarms are a run's; attach to a run (dive view hub://RUN --foxglove)")
        answered = self._markers.acknowledged
        answered.clear()
        s.send(ground_text(ACK_REQUEST, "", {}), wait=False, flags=GROUND_FLAG)
        if not answered.wait(MARK_WAIT_S):
            raise ServiceError(f"ack: the run did not answer within {MARK_WAIT_S:g} s")
        return {"command": "ack", "accepted": True, "result": "ACCEPTED", "reason": "", "mode": control.mode_name(s),
                "message": self._markers.ack_answer}

    def _dump(self, s: Session, body: dict[str, Any]) -> dict[str, Any]:
        """VALUES and POLICY (or one of them) fetched now; each published on /dump/<KIND> and as an image."""
        kind = body.get("kind", "both")
        kinds = {"values": [DumpKind.VALUES], "policy": [DumpKind.POLICY],
                 "both": [DumpKind.POLICY, DumpKind.VALUES]}.get(kind) if isinstance(kind, str) else None
        if kinds is None:
            raise ServiceError('dump: kind is "values", "policy" or "both"')
        said = []
        for one in kinds:  # POLICY first: the value image greys the cells the policy says were never left
            snapshot = s.dump(one, timeout_s=10.0)
            said.append(f"{one.name.lower()} of episode {snapshot.episode} ({len(snapshot.values())} values)")
        return {"command": "CMD_DUMP", "accepted": True, "result": "ACCEPTED", "reason": "",
                "mode": control.mode_name(s), "message": "dumped " + ", ".join(said)}
