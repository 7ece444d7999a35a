"""The door in front of Foxglove's server: only the run's owner gets through, a bounded number at a time, each with a
bounded queue (issue 38 N1, N4, N5).

Foxglove's WebSocket protocol has no login and the SDK's server has no hook at accept, so the port the operator is
given is ours: a loopback TCP listener that reads the client's HTTP upgrade request and lets it through only if
- the peer's process runs as our user, by the kernel's socket table (links/peer.py: Linux), or, where the kernel
  cannot tell (macOS), the request's path is the run's secret (`ws://127.0.0.1:PORT/<token>`, printed to the owner);
- fewer than MAX_CLIENTS are through already.
Anything else is answered 403 or 503 and closed; bytes that are no HTTP request within REQUEST_LIMIT bytes or
REQUEST_TIMEOUT_S are closed unanswered. A client that is let through is piped to the SDK's server on a second,
ephemeral loopback port, and its first WebSocket frame there is ours: a client-channel advertisement whose topic
holds a secret of this process (`owner_topic`), which the server's listener takes as the proof that this client
came through the door (live.py). A connection straight to that inner port (anyone can find it) never sends it, and
is given no channel data, no parameter and no service (live.py, channels.py): it sees the problems-list lines
(the SDK broadcasts them) and the channel and service names.

A client that does not read is not queued for without end: once CLIENT_BUFFER_BYTES wait for it, it is dropped (and
counted); the SDK's queue for it stays empty because this door reads it.
"""

from __future__ import annotations

import contextlib
import hmac
import json
import os
import secrets
import selectors
import socket
import threading
import time
from dataclasses import dataclass, field

from groundstation.links.peer import peer_is_owner

MAX_CLIENTS = 8  # Foxglove windows at once: the operator's app, a second layout, a script; 40 took 1 GB (N4)
REQUEST_LIMIT = 8192  # an HTTP upgrade request is a few hundred bytes
REQUEST_TIMEOUT_S = 3.0  # a connection that has not sent its request by then is closed
CLIENT_BUFFER_BYTES = 4 * 1024 * 1024  # queued for one client before it is dropped as too slow
INNER_CONNECT_S = 2.0
FOREIGN_PENDING = 64  # another user's connections waiting to be answered 403; more are closed at accept
OWNER_CHANNEL_ID = 0xFFFF_FFF0  # far from the ids the Foxglove app gives its own channels (from 1 up)
_END = b"\r\n\r\n"
_FORBIDDEN = b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"
_FULL = b"HTTP/1.1 503 Service Unavailable\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"


@dataclass
class GateCounts:
    """What the door did, for the run's last lines and the tests."""

    admitted: int = 0
    refused_user: int = 0  # another user's process (or no token where the kernel cannot tell)
    refused_full: int = 0
    closed_junk: int = 0  # no HTTP request: random bytes, too long, too slow
    dropped_slow: int = 0  # let through, then dropped for not reading


@dataclass(eq=False)
class _Door:
    client: socket.socket
    accepted_s: float
    owner: bool | None  # the kernel's answer at accept (links/peer.py); None: it cannot tell, the token decides
    request: bytearray = field(default_factory=bytearray)
    inner: socket.socket | None = None
    response: bytearray = field(default_factory=bytearray)
    upgraded: bool = False
    to_client: bytearray = field(default_factory=bytearray)
    to_inner: bytearray = field(default_factory=bytearray)
    closing: bool = False  # close once to_client is sent (a refusal)


def masked_text_frame(text: bytes) -> bytes:
    """A WebSocket text frame as a client sends it (RFC 6455: masked), for the proof the door adds."""
    mask = os.urandom(4)
    length = len(text)
    size = bytes([0x80 | length]) if length < 126 else bytes([0x80 | 126]) + length.to_bytes(2, "big")
    header = bytes([0x81]) + size
    return header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(text))


class FoxgloveGate:
    """The listener on the operator's port (bound at once: a port in use raises OSError here); start() serves."""

    def __init__(self, host: str, port: int, owner_topic: str) -> None:
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        self.port: int = self._listener.getsockname()[1]
        self._inner = (host, 0)
        self.token = secrets.token_hex(16)  # the path a client must ask for where the kernel cannot name its user
        self._proof = masked_text_frame(json.dumps({"op": "advertise", "channels": [
            {"id": OWNER_CHANNEL_ID, "topic": owner_topic, "encoding": "json", "schemaName": ""}]}).encode())
        self.counts = GateCounts()
        self._doors: list[_Door] = []
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ, None)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="dive-foxglove-gate", daemon=True)

    def start(self, inner_port: int) -> None:
        """Serve, piping to the SDK's server on `inner_port` (bound after this door, which the operator's port is)."""
        self._inner = (self._inner[0], inner_port)
        self._thread.start()

    @property
    def through(self) -> int:
        return sum(1 for door in self._doors if door.inner is not None)

    def close(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        for door in list(self._doors):
            self._drop(door)
        with contextlib.suppress(OSError):
            self._listener.close()
        self._selector.close()

    # ------------------------------------------------------------------ the door's thread
    def _serve(self) -> None:
        while not self._stop.is_set():
            pending = any(door.to_client or door.to_inner for door in self._doors)
            for key, _ in self._selector.select(0.02 if pending else 0.25):
                if key.data is None:
                    self._accept()
                else:
                    door, from_client = key.data
                    self._read(door, from_client)
            now_s = time.monotonic()
            for door in list(self._doors):
                if door.inner is None and not door.closing and now_s - door.accepted_s > REQUEST_TIMEOUT_S:
                    self.counts.closed_junk += 1
                    self._drop(door)
                else:
                    self._flush(door)

    def _accept(self) -> None:
        try:
            sock, _ = self._listener.accept()
        except OSError:
            return
        # whose it is, asked once at accept: another user's connections are counted apart, so that a flood of them
        # never takes the slots the owner's app needs (they are answered 403 once their request is read)
        owner = peer_is_owner(sock)
        foreign = sum(1 for door in self._doors if door.owner is False)
        ours = len(self._doors) - foreign
        if (owner is False and foreign >= FOREIGN_PENDING) or (owner is not False and ours >= 2 * MAX_CLIENTS + 16):
            self.counts.refused_full += 1  # a flood costs one close each
            with contextlib.suppress(OSError):
                sock.close()
            return
        sock.setblocking(False)
        door = _Door(sock, time.monotonic(), owner)
        self._doors.append(door)
        self._selector.register(sock, selectors.EVENT_READ, (door, True))

    def _read(self, door: _Door, from_client: bool) -> None:
        sock = door.client if from_client else door.inner
        if sock is None:
            return
        try:
            data = sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._drop(door)
        elif door.closing:
            return  # a refused client's further bytes: ignored until its answer is sent
        elif from_client and door.inner is None:
            self._request(door, data)
        elif from_client:
            door.to_inner += data
            if len(door.to_inner) > CLIENT_BUFFER_BYTES:
                self._drop(door)
        elif not door.upgraded:
            self._response(door, data)
        else:
            door.to_client += data
            if len(door.to_client) > CLIENT_BUFFER_BYTES:
                self.counts.dropped_slow += 1
                self._drop(door)

    def _request(self, door: _Door, data: bytes) -> None:
        door.request += data
        end = door.request.find(_END)
        if end < 0:
            if len(door.request) > REQUEST_LIMIT:
                self.counts.closed_junk += 1
                self._drop(door)
            return
        if end > REQUEST_LIMIT or not door.request.startswith(b"GET "):
            self.counts.closed_junk += 1
            self._drop(door)
            return
        if not self._admits(door):
            self.counts.refused_user += 1
            self._refuse(door, _FORBIDDEN)
        elif self.through >= MAX_CLIENTS:
            self.counts.refused_full += 1
            self._refuse(door, _FULL)
        else:
            self._open_inner(door)

    def _admits(self, door: _Door) -> bool:
        if door.owner is not None:
            return door.owner
        path = bytes(door.request[4:door.request.find(b" ", 4)])  # GET <path> HTTP/1.1
        return hmac.compare_digest(path.strip(b"/").split(b"?")[0], self.token.encode())

    def _refuse(self, door: _Door, answer: bytes) -> None:
        door.to_client += answer
        door.closing = True

    def _open_inner(self, door: _Door) -> None:
        try:
            inner = socket.create_connection(self._inner, timeout=INNER_CONNECT_S)
        except OSError:
            self._drop(door)
            return
        inner.setblocking(False)
        inner.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        door.inner = inner
        end = door.request.find(_END) + len(_END)
        door.to_inner += door.request[:end]
        door.request = door.request[end:]  # frames the client sent at once: after the proof, once upgraded
        self.counts.admitted += 1
        self._selector.register(inner, selectors.EVENT_READ, (door, False))

    def _response(self, door: _Door, data: bytes) -> None:
        door.response += data
        end = door.response.find(_END)
        if end < 0:
            if len(door.response) > REQUEST_LIMIT:
                self._drop(door)
            return
        end += len(_END)
        door.to_client += door.response[:end]
        if door.response.startswith(b"HTTP/1.1 101"):
            door.upgraded = True
            door.to_inner += self._proof + door.request  # the proof is the first frame the server reads
            door.request = bytearray()
            door.to_client += door.response[end:]
        else:
            door.closing = True
        door.response = bytearray()

    def _flush(self, door: _Door) -> None:
        for buffer, sock in ((door.to_client, door.client), (door.to_inner, door.inner)):
            if not buffer or sock is None:
                continue
            try:
                sent = sock.send(buffer)
            except (BlockingIOError, InterruptedError):
                continue
            except OSError:
                self._drop(door)
                return
            del buffer[:sent]
        if door.closing and not door.to_client:
            self._drop(door)

    def _drop(self, door: _Door) -> None:
        if door in self._doors:
            self._doors.remove(door)
        for sock in (door.client, door.inner):
            if sock is None:
                continue
            with contextlib.suppress(KeyError, ValueError, OSError):
                self._selector.unregister(sock)
            with contextlib.suppress(OSError):
                sock.close()
