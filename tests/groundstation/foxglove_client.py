"""A Foxglove WebSocket protocol client for tests: the JSON ops and binary frames the Foxglove app sends and reads."""

from __future__ import annotations

import itertools
import json
import struct
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

SUBPROTOCOL = "foxglove.sdk.v1"
# How long an answer may take at most (a wait ends when it comes): the agent's first use of a kernel compiles it
# on a cold numba cache, tens of seconds when another test worker is compiling too (as in CI's fresh clone).
ANSWER_TIMEOUT_S = 60.0
MESSAGE_DATA, SERVICE_CALL_RESPONSE = 0x01, 0x03  # server -> client binary opcodes
SERVICE_CALL_REQUEST = 0x02  # client -> server


@dataclass
class FoxgloveClient:
    ws: ClientConnection
    channels: dict[str, dict[str, Any]] = field(default_factory=dict)  # topic -> advertised channel
    services: dict[str, dict[str, Any]] = field(default_factory=dict)  # name -> advertised service
    messages: dict[int, list[bytes]] = field(default_factory=dict)  # subscription id -> payloads
    log_times: dict[int, list[int]] = field(default_factory=dict)  # subscription id -> their log times (ns)
    responses: dict[int, bytes] = field(default_factory=dict)  # call id -> response payload
    failures: dict[int, str] = field(default_factory=dict)  # call id -> serviceCallFailure message
    parameter_replies: dict[str, list[dict[str, Any]]] = field(default_factory=dict)  # request id -> parameters
    statuses: list[dict[str, Any]] = field(default_factory=list)
    server_info: dict[str, Any] = field(default_factory=dict)
    _ids: itertools.count[int] = field(default_factory=lambda: itertools.count(1))

    @classmethod
    @contextmanager
    def connected(cls, port: int, path: str = "") -> Iterator[FoxgloveClient]:
        """A client of the server on 127.0.0.1:PORT (PATH: the run's secret where the kernel cannot name a peer),
        speaking the subprotocol the Foxglove app offers."""
        # close_timeout: a client subscribed to SAMPLEs at --speed max has a backlog in front of the server's close
        # frame; waiting the default 10 s for it tests nothing
        with connect(f"ws://127.0.0.1:{port}{path}", subprotocols=[SUBPROTOCOL],  # type: ignore[list-item]
                     open_timeout=5, close_timeout=0.5) as ws:
            yield cls(ws)

    def pump(self, until: Callable[[], bool], timeout_s: float = 5.0) -> bool:
        """Read what the server sends until `until()` holds or the time is up; whether it held."""
        deadline = time.monotonic() + timeout_s
        while not until():
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            try:
                frame = self.ws.recv(timeout=min(left, 0.2))
            except TimeoutError:
                continue
            except ConnectionClosed:  # the server went away (its run ended): nothing more will come
                return until()
            self._take(frame)
        return True

    def _take(self, frame: str | bytes) -> None:
        if isinstance(frame, bytes):
            if frame[0] == MESSAGE_DATA:
                subscription, log_time = struct.unpack_from("<IQ", frame, 1)
                self.messages.setdefault(subscription, []).append(frame[13:])
                self.log_times.setdefault(subscription, []).append(log_time)
            elif frame[0] == SERVICE_CALL_RESPONSE:
                _, call, length = struct.unpack_from("<III", frame, 1)
                self.responses[call] = frame[13 + length:]
            return
        op = json.loads(frame)
        kind = op["op"]
        if kind == "serverInfo":
            self.server_info = op
        elif kind == "advertise":
            self.channels.update({c["topic"]: c for c in op["channels"]})
        elif kind == "advertiseServices":
            self.services.update({s["name"]: s for s in op["services"]})
        elif kind == "parameterValues":
            self.parameter_replies[op.get("id", "")] = op["parameters"]
        elif kind == "serviceCallFailure":
            self.failures[op["callId"]] = op["message"]
        elif kind == "status":
            self.statuses.append(op)

    def subscribe(self, topic: str) -> int:
        subscription = next(self._ids)
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [
            {"id": subscription, "channelId": self.channels[topic]["id"]}]}))
        return subscription

    def get_parameters(self, names: list[str], timeout_s: float = ANSWER_TIMEOUT_S) -> list[dict[str, Any]]:
        request = f"get-{next(self._ids)}"
        self.ws.send(json.dumps({"op": "getParameters", "parameterNames": names, "id": request}))
        assert self.pump(lambda: request in self.parameter_replies, timeout_s), f"no answer to {request}"
        return self.parameter_replies[request]

    def set_parameters(self, values: dict[str, Any], timeout_s: float = ANSWER_TIMEOUT_S) -> list[dict[str, Any]]:
        request = f"set-{next(self._ids)}"
        self.ws.send(json.dumps({"op": "setParameters", "id": request,
                                 "parameters": [{"name": k, "value": v} for k, v in values.items()]}))
        assert self.pump(lambda: request in self.parameter_replies, timeout_s), f"no answer to {request}"
        return self.parameter_replies[request]

    def call(self, service: str, request: dict[str, Any] | None = None,
             timeout_s: float = ANSWER_TIMEOUT_S) -> dict[str, Any]:
        """Call a service with a JSON request; its JSON response, or {"failure": message}."""
        call = next(self._ids)
        encoding = b"json"
        payload = json.dumps(request or {}).encode()
        self.ws.send(struct.pack("<BIII", SERVICE_CALL_REQUEST, self.services[service]["id"], call, len(encoding))
                     + encoding + payload)
        assert self.pump(lambda: call in self.responses or call in self.failures, timeout_s), f"{service}: no answer"
        if call in self.failures:
            return {"failure": self.failures[call]}
        return json.loads(self.responses[call])
