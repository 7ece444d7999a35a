"""The TCP front of the emulated agent: clients connect here, bytes pass unchanged to QEMU's UART0.

QEMU has the board's UART on a socket we hand it (firmware_qemu.uart_pair), but a UART has no carrier line: the firmware
cannot see a TCP client come or go, and SPEC.md 1.1 wants a HELLO on every new TCP connection. The relay
keeps one connection to QEMU's UART0 for the whole run and, for every new client, writes one byte to the
board's UART2 (its link-event line), on which the firmware calls agent_link_up(). As the virtual agent's
server does, a second client replaces the first, which is told so (SPEC.md s.4, *A link taken by another ground*).
"""

from __future__ import annotations

import select
import socket
import threading

from protocol.link_taken import link_taken_notice
from simulator.serve.transport import limit_unsent

_CHUNK = 4096
# QEMU writes the UART's bytes to its socket one by one as the firmware sends them. Bytes that follow
# within this time are forwarded together, so a burst (an ACK and the reply behind it) reaches the client
# in one segment, as from the Python agent's server, instead of being cut wherever a recv() happened to wake.
_BURST_S = 0.002
BURST_MAX_BYTES = 4096
# Flow control at speed max: the firmware runs only while its UART can send (it waits on TX_FULL, which QEMU holds
# while its socket refuses bytes), so every buffer between it and the ground is agent time it may run ahead of the
# ground, at ~1 kB per agent second. Left to the kernel, the TCP buffers on loopback grew to a megabyte and more
# (ten minutes of agent time) that a slow ground (a loaded machine) then saw late and commanded late (issue 30:
# `dive fit --excite` overran the agent's max_dive_s). So QEMU's socket is one we size (firmware_qemu.uart_pair),
# this relay holds one burst, and the client's socket few unsent bytes (limit_unsent): the backlog stays in the
# firmware, which waits, and speed max is bounded by the ground's reading.
LINK_UP = b"\x01"
NOTICE_WAIT_S = 1.0  # for room in a slow reader's buffer for the notice
LINGER_S = 5.0  # a replaced client is read (and ignored) until it closes, at most this long: no reset loses the notice


class LinkRelay:
    """Listens on (host, port); forwards between the current client and QEMU's link socket."""

    def __init__(self, host: str, port: int, qemu_link: socket.socket, qemu_events: socket.socket) -> None:
        self._listener = socket.create_server((host, port))
        bound_host, bound_port = self._listener.getsockname()[:2]
        self.address = f"tcp://{bound_host}:{bound_port}"
        self._link = qemu_link
        self._events = qemu_events
        self._client: socket.socket | None = None
        self._aligned = False  # the current client starts at a frame boundary (it was sent none of a frame's start)
        self._mid_frame = False  # QEMU's stream so far ends inside a frame (its last byte was not a 0x00)
        self._lock = threading.Lock()
        self._closed = threading.Event()
        threading.Thread(target=self._accept_loop, name="relay-accept", daemon=True).start()
        threading.Thread(target=self._from_qemu, name="relay-from-qemu", daemon=True).start()

    def _accept_loop(self) -> None:
        while not self._closed.is_set():
            try:
                client, _ = self._listener.accept()
            except OSError:
                return
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            limit_unsent(client)
            with self._lock:
                old, self._client = self._client, client
                self._aligned = False
            if old is not None:
                _tell_replaced(old)
            try:
                self._events.sendall(LINK_UP)
            except OSError:
                return
            threading.Thread(target=self._from_client, args=(client,), name="relay-from-client", daemon=True).start()

    def _from_client(self, client: socket.socket) -> None:
        while True:
            try:
                data = client.recv(_CHUNK)
            except OSError:
                data = b""
            if not data:
                break
            with self._lock:
                current = self._client is client
            if not current:
                continue  # a replaced client's bytes go nowhere; it is read until it closes (_tell_replaced)
            try:
                self._link.sendall(data)
            except OSError:
                break
        with self._lock:
            if self._client is client:
                self._client = None
        _close(client)

    def _from_qemu(self) -> None:
        while not self._closed.is_set():
            try:
                data = self._link.recv(_CHUNK)
                while data and len(data) < BURST_MAX_BYTES and select.select([self._link], [], [], _BURST_S)[0]:
                    more = self._link.recv(_CHUNK)
                    if not more:
                        break
                    data += more
            except (OSError, ValueError):
                return
            if not data:
                return  # QEMU ended
            with self._lock:
                client = self._client
                mid_frame, self._mid_frame = self._mid_frame, not data.endswith(b"\x00")
                if client is not None and not self._aligned:
                    # A new client starts at a frame boundary, never inside a frame another client got the start
                    # of (the 0x00 is kept: an empty chunk is ignored by any decoder). Only then: a chunk that
                    # starts a frame (the board idle between steps, its next frame the ACK of the client's first
                    # command) is whole; cutting it to its first 0x00 lost that ACK (`dive check
                    # sim://?firmware=qemu&speed=5`: "the agent does not answer commands", one start in two).
                    boundary = data.find(b"\x00") if mid_frame else 0
                    data = data[boundary:] if boundary >= 0 else b""
                    self._aligned = boundary >= 0
            if client is None or not data:
                continue  # nobody listening: the bytes are lost, as on a radio link without a ground station
            try:
                client.sendall(data)
            except OSError:
                with self._lock:
                    if self._client is client:
                        self._client = None
                _close(client)

    def close(self) -> None:
        self._closed.set()
        _close(self._listener)
        with self._lock:
            client, self._client = self._client, None
        if client is not None:
            _close(client)


def _tell_replaced(old: socket.socket) -> None:
    """The "link taken" TEXT to a replaced client, then our FIN; its reader thread reads on until it closes (or
    LINGER_S), so that our close is no reset that would discard the TEXT unread. The relay does not know the
    agent's time: t_us is 0 (a ground acts on the text)."""
    try:
        old.settimeout(NOTICE_WAIT_S)
        old.sendall(link_taken_notice())
        old.shutdown(socket.SHUT_WR)
        old.settimeout(LINGER_S)
    except OSError:
        _close(old)


def _close(s: socket.socket) -> None:
    try:
        s.shutdown(socket.SHUT_RDWR)
    except OSError:
        pass
    s.close()
