"""The door on 127.0.0.1 in front of the web viewer's private servers: the run's owner gets through, nobody else
(issue 38).

The browser is given this door's two ports (the page, and the gRPC data stream the page's URL names), and so is the
run's own recording stream. At accept, the kernel's socket table names the peer's user (links/peer.py, as for the
hub and the Foxglove door): the run's user or root is let through, anyone else is answered `403 Forbidden` and
closed before a byte of theirs is read (a flood of them costs one close each and takes no slot). A connection let
through is joined to a socket connected to the same server inside the private network (web_bridge.py hands it
over) and its bytes are copied both ways by two threads: a side is read only as fast as the other takes it, so
nothing queues here. Unlike the Foxglove door, nothing stands behind this one: the servers' own ports are in a
network no other process is in.
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
from dataclasses import dataclass
from pathlib import Path

from groundstation.links.peer import peer_is_owner

MAX_CONNECTIONS = 64  # the owner's browser tabs (~6 connections each for the page, a few for the data) and the run
HAND_OVER_WAIT_S = 5.0  # the bridge answers in a millisecond; a loaded machine may take a while
CHUNK = 64 * 1024
FORBIDDEN = b"HTTP/1.1 403 Forbidden\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"


@dataclass
class WebGateCounts:
    """What the door did, for the tests."""

    admitted: int = 0
    refused_user: int = 0  # another user's process, or a peer the kernel cannot name
    refused_full: int = 0
    failed_inner: int = 0  # the private server did not take the connection (it is stopping)


def connected_inside(bridge: Path, which: bytes) -> socket.socket:
    """A blocking TCP socket connected to one of the private servers (`w` the page, `g` the data stream)."""
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as ask:
        ask.settimeout(HAND_OVER_WAIT_S)
        ask.connect(str(bridge))
        ask.sendall(which)
        answer, fds, _, _ = socket.recv_fds(ask, 1, 1)
    if answer != b"+" or len(fds) != 1:
        for fd in fds:
            with contextlib.suppress(OSError):
                socket.close(fd)
        raise ConnectionRefusedError("the web viewer's private server refused the connection")
    inner = socket.socket(fileno=fds[0])
    inner.setblocking(True)
    return inner


class WebGate:
    """Listeners on `host` at each port of `ports` (bound at once: a port in use raises OSError here), each joined
    to the private server named by its byte; start() serves from a thread of its own."""

    def __init__(self, host: str, ports: dict[bytes, int], bridge: Path) -> None:
        self._bridge = bridge
        self._listeners: dict[socket.socket, bytes] = {}
        try:
            for which, port in ports.items():
                listener = socket.create_server((host, port))
                self._listeners[listener] = which
        except OSError:
            self._close_listeners()
            raise
        self.ports = {which: listener.getsockname()[1] for listener, which in self._listeners.items()}
        self.counts = WebGateCounts()
        self._open: set[socket.socket] = set()
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="dive-web-gate", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def close(self) -> None:
        """Stop accepting and cut every connection through (the viewer is going away)."""
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(2.0)
        self._close_listeners()
        with self._lock:
            open_now, self._open = set(self._open), set()
        for sock in open_now:
            with contextlib.suppress(OSError):
                sock.shutdown(socket.SHUT_RDWR)
            with contextlib.suppress(OSError):
                sock.close()

    def _close_listeners(self) -> None:
        for listener in self._listeners:
            with contextlib.suppress(OSError):
                listener.close()

    def _serve(self) -> None:
        with selectors.DefaultSelector() as selector:
            for listener in self._listeners:
                selector.register(listener, selectors.EVENT_READ, listener)
            while not self._stop.is_set():
                for key, _ in selector.select(0.25):
                    listener = key.data
                    try:
                        client, _ = listener.accept()
                    except OSError:
                        continue
                    self._admit(client, self._listeners[listener])

    def _admit(self, client: socket.socket, which: bytes) -> None:
        if peer_is_owner(client) is not True:  # None (no socket table) is refused too: no secret stands in here
            self.counts.refused_user += 1
            self._refuse(client)
            return
        with self._lock:
            full = len(self._open) // 2 >= MAX_CONNECTIONS  # two sockets a connection
        if full:
            self.counts.refused_full += 1
            self._refuse(client, b"")
            return
        try:
            inner = connected_inside(self._bridge, which)
        except OSError:
            self.counts.failed_inner += 1
            self._refuse(client, b"")
            return
        self.counts.admitted += 1
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        inner.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        with self._lock:
            self._open.update((client, inner))
        ended = threading.Barrier(2, action=lambda: self._forget(client, inner))
        for source, sink in ((client, inner), (inner, client)):
            threading.Thread(target=self._copy, args=(source, sink, ended), name="dive-web-gate-pipe",
                             daemon=True).start()

    @staticmethod
    def _refuse(client: socket.socket, answer: bytes = FORBIDDEN) -> None:
        with contextlib.suppress(OSError):
            client.setblocking(False)
            client.send(answer)  # a few bytes into an empty buffer: never blocks the door
        with contextlib.suppress(OSError):
            client.close()

    @staticmethod
    def _copy(source: socket.socket, sink: socket.socket, ended: threading.Barrier) -> None:
        """One direction: read as fast as the other side takes it; at its end, end the other side's writing."""
        try:
            while data := source.recv(CHUNK):
                sink.sendall(data)
        except OSError:
            with contextlib.suppress(OSError):
                source.shutdown(socket.SHUT_RDWR)  # a reset on one side ends the other direction too
        finally:
            with contextlib.suppress(OSError):
                sink.shutdown(socket.SHUT_WR)
            with contextlib.suppress(threading.BrokenBarrierError):
                ended.wait()

    def _forget(self, client: socket.socket, inner: socket.socket) -> None:
        with self._lock:
            self._open.difference_update((client, inner))
        for sock in (client, inner):
            with contextlib.suppress(OSError):
                sock.close()
