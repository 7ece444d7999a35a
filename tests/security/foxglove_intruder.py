"""Another local user's attack on a run's Foxglove server (run as that user by test_foxglove_owner.py): the system
Python only, a WebSocket client of its own (RFC 6455, as small as it gets), Foxglove's protocol as the app speaks it.

argv: a port (the one the run printed, or the SDK's own one behind it, found in /proc/net/tcp as any user can).
It reads what it is sent, subscribes to every channel, gets and sets parameters, calls the services; prints one
JSON line: what it was let in to and what it got.
"""

from __future__ import annotations

import base64
import json
import os
import socket
import struct
import sys
import time

SUBPROTOCOL = "foxglove.sdk.v1"


def frame(opcode: int, payload: bytes) -> bytes:
    mask = os.urandom(4)
    n = len(payload)
    size = bytes([0x80 | n]) if n < 126 else bytes([0x80 | 126]) + struct.pack(">H", n) if n < 65536 else \
        bytes([0x80 | 127]) + struct.pack(">Q", n)
    return bytes([0x80 | opcode]) + size + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


class Client:
    def __init__(self, port: int) -> None:
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=2.0)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                           f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n"
                           f"Sec-WebSocket-Protocol: {SUBPROTOCOL}\r\n\r\n").encode())
        self.buffer = b""
        while b"\r\n\r\n" not in self.buffer:
            chunk = self.sock.recv(4096)
            if not chunk:
                break
            self.buffer += chunk
        head, _, self.buffer = self.buffer.partition(b"\r\n\r\n")
        self.status = head.split(b"\r\n", 1)[0].decode(errors="replace")

    @property
    def upgraded(self) -> bool:
        return " 101 " in self.status + " "

    def send_json(self, op: dict[str, object]) -> None:
        self.sock.sendall(frame(0x1, json.dumps(op).encode()))

    def send_binary(self, data: bytes) -> None:
        self.sock.sendall(frame(0x2, data))

    def frames(self, seconds: float) -> list[tuple[int, bytes]]:
        """Every whole frame that comes within `seconds`."""
        got: list[tuple[int, bytes]] = []
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            while len(self.buffer) >= 2:
                n, at = self.buffer[1] & 0x7F, 2
                if n == 126:
                    n, at = struct.unpack_from(">H", self.buffer, 2)[0], 4
                elif n == 127:
                    n, at = struct.unpack_from(">Q", self.buffer, 2)[0], 10
                if len(self.buffer) < at + n:
                    break
                got.append((self.buffer[0] & 0x0F, self.buffer[at:at + n]))
                self.buffer = self.buffer[at + n:]
            try:
                self.sock.settimeout(max(0.01, deadline - time.monotonic()))
                chunk = self.sock.recv(65536)
            except OSError:
                continue
            if not chunk:
                break
            self.buffer += chunk
        return got


def main() -> None:
    port = int(sys.argv[1])
    report: dict[str, object] = {"status": "", "channels": 0, "services": 0, "data": 0, "parameters": 0,
                                 "answers": 0, "failures": 0}
    try:
        client = Client(port)
    except OSError as e:
        report["status"] = type(e).__name__
        print(json.dumps(report))
        return
    report["status"] = client.status
    if client.upgraded:
        channels: dict[int, str] = {}
        services: dict[int, str] = {}

        def take(frames: list[tuple[int, bytes]]) -> None:
            for opcode, payload in frames:
                if opcode == 0x2 and payload[:1] == b"\x01":
                    report["data"] = int(report["data"]) + 1  # type: ignore[call-overload]
                elif opcode == 0x2 and payload[:1] == b"\x03":
                    report["answers"] = int(report["answers"]) + 1  # type: ignore[call-overload]
                elif opcode == 0x1:
                    op = json.loads(payload)
                    if op["op"] == "advertise":
                        channels.update({c["id"]: c["topic"] for c in op["channels"]})
                    elif op["op"] == "advertiseServices":
                        services.update({s["id"]: s["name"] for s in op["services"]})
                    elif op["op"] == "parameterValues":
                        report["parameters"] = int(report["parameters"]) + len(op["parameters"])  # type: ignore
                    elif op["op"] == "serviceCallFailure":
                        report["failures"] = int(report["failures"]) + 1  # type: ignore[call-overload]

        take(client.frames(1.5))
        client.send_json({"op": "subscribe", "subscriptions": [{"id": i + 1, "channelId": c}
                                                               for i, c in enumerate(channels)]})
        client.send_json({"op": "subscribeParameterUpdates", "parameterNames": ["target_depth_m", "z_tol_m"]})
        client.send_json({"op": "getParameters", "parameterNames": [], "id": "get"})
        client.send_json({"op": "setParameters", "id": "set", "parameters": [{"name": "target_depth_m", "value": 1.9}]})
        for call, (service, name) in enumerate(services.items()):
            if name in ("surface", "stop", "pause", "mark"):
                body = json.dumps({"text": "INTRUDER was here"} if name == "mark" else {}).encode()
                client.send_binary(struct.pack("<BIII", 0x02, service, call, 4) + b"json" + body)
        take(client.frames(3.0))
        report["channels"], report["services"] = len(channels), len(services)
    print(json.dumps(report))


if __name__ == "__main__":
    main()
