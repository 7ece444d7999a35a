"""The two ways in: a TCP listener serving one client at a time (the ESP8266 bridge) and a pseudo-terminal (USB)."""

from __future__ import annotations

import contextlib
import errno
import os
import select
import selectors
import socket
import threading
import time
import tty
from abc import ABC, abstractmethod
from collections.abc import Callable

from simulator.errors import SimulatorError

READ_BYTES = 65536
# Bytes the kernel may hold unsent for a client (TCP_NOTSENT_LOWAT): few, so bytes the ground has not taken wait in
# our out buffer, where the server sees them and paces the program (server.py), not in the kernel. Not a small
# SO_SNDBUF: that also counts bytes sent but not yet acknowledged, so with a reader that delays its ACKs (40 ms,
# as Linux does for a peer that sends little) the agent could send one segment per delayed ACK.
UNSENT_BYTES = 4 * 1024
SEND_BUFFER_BYTES = 4 * 1024  # where TCP_NOTSENT_LOWAT does not exist: the send buffer itself, as small


def limit_unsent(sock: socket.socket) -> None:
    """Let the kernel hold few unsent bytes for this client (UNSENT_BYTES), so a slow reader makes us wait."""
    notsent_lowat = getattr(socket, "TCP_NOTSENT_LOWAT", None)
    if notsent_lowat is not None:
        sock.setsockopt(socket.IPPROTO_TCP, notsent_lowat, UNSENT_BYTES)
    else:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER_BYTES)


def tell_replaced(old: socket.socket, notice: bytes) -> None:
    """Send the old client the replaced notice, then end our side with a FIN, not a reset: a socket closed with
    unread bytes in it resets the connection, and a reset makes Linux drop what the peer has not read yet."""
    def drain() -> None:
        with contextlib.suppress(OSError):
            while old.recv(READ_BYTES):
                pass

    drain()
    with contextlib.suppress(OSError):
        # Waiting up to a second for room: a full send buffer (a slow reader) would otherwise swallow the notice,
        # and the old ground, seeing only the close, would reconnect and take the link back.
        old.settimeout(REPLACED_NOTICE_WAIT_S)
        old.sendall(notice)  # protocol.link_taken: 0x00 first, ending a partial frame sent before it
        old.shutdown(socket.SHUT_WR)
    old.setblocking(False)
    drain()
    # The old ground may still be writing (a command sent as the new one connected): a byte of it arriving after
    # the drain and before our close would make the close a reset, and the notice would be lost with it (the
    # takeover test's "the run did not end": it reconnected and took the link back). A copy of the socket stays
    # open, read to the old ground's own close (it closes on the notice) or for at most LINGER_S; the caller's
    # close() of `old` then ends nothing.
    with contextlib.suppress(OSError):
        lingering = old.dup()
        threading.Thread(target=_read_to_close, args=(lingering,), name="replaced-linger", daemon=True).start()


def _read_to_close(sock: socket.socket) -> None:
    """Read and drop what a replaced client still sends until it closes (or LINGER_S), then close."""
    deadline = time.monotonic() + LINGER_S
    with contextlib.suppress(OSError), sock:
        sock.setblocking(True)
        while (left := deadline - time.monotonic()) > 0:
            sock.settimeout(left)
            if not sock.recv(READ_BYTES):
                return


class TransportError(SimulatorError, OSError):
    """The port cannot be opened (address in use, no pty available)."""


BITS_PER_BYTE = 10  # a UART's 8N1 frame: a start bit, 8 data bits, a stop bit
FIFO_BYTES = 64  # what a UART takes at once (its transmit FIFO): the burst a paced link allows


class Pacer:
    """Bytes leave at a UART's rate (baud / 10 a wall second), as through the ESP8266's 115 200-baud serial."""

    def __init__(self, baud: int, clock: Callable[[], float] = time.monotonic) -> None:
        self.bytes_per_s = baud / BITS_PER_BYTE
        self._clock = clock
        self._credit = float(FIFO_BYTES)
        self._at = clock()

    def allowed(self) -> int:
        """Bytes the UART takes now."""
        now = self._clock()
        self._credit = min(float(FIFO_BYTES), self._credit + (now - self._at) * self.bytes_per_s)
        self._at = now
        return int(self._credit)

    def spent(self, count: int) -> None:
        self._credit -= count

    def wait_s(self, pending: int) -> float:
        """Wall seconds until the UART takes min(pending, its FIFO) bytes: when the loop should flush again."""
        want = min(pending, FIFO_BYTES)
        return max(0.0, (want - self._credit) / self.bytes_per_s)


class Transport(ABC):
    """One client at a time; bytes out are buffered and flushed when the OS takes them.

    The server sets on_connect / on_data / on_disconnect; `poll` is called every loop iteration.
    """

    address: str  # what to print on the first line: tcp://HOST:PORT or the pty's device path

    def __init__(self, selector: selectors.BaseSelector) -> None:
        self.selector = selector
        self.outbuf = bytearray()
        self.pacer: Pacer | None = None  # --baud: bytes leave at a UART's rate
        self.on_connect: Callable[[], None] = lambda: None
        self.on_data: Callable[[bytes], None] = lambda data: None
        self.on_disconnect: Callable[[], None] = lambda: None
        self.on_replaced: Callable[[], bytes] = lambda: b""  # what to tell a client a new connection replaces

    @property
    @abstractmethod
    def connected(self) -> bool:
        """A client is there to take bytes."""

    def send(self, data: bytes) -> None:
        if self.connected:
            self.outbuf += data

    @abstractmethod
    def flush(self) -> None:
        """Write what the OS (and a paced link's UART) takes of the out buffer now, without blocking."""

    def _sendable(self) -> bytes | bytearray:
        """What to offer the OS now: all of the out buffer, or on a paced link what the UART takes."""
        if self.pacer is None:
            return self.outbuf
        return self.outbuf[: self.pacer.allowed()]

    def _sent(self, offered: int, sent: int) -> int:
        """Account `sent` bytes; the selector events to wait for (writable only if the OS refused bytes)."""
        if self.pacer is not None:
            self.pacer.spent(sent)
        del self.outbuf[:sent]
        return selectors.EVENT_READ | (selectors.EVENT_WRITE if self.outbuf and sent < offered else 0)

    def poll(self) -> None:  # noqa: B027 - a hook: TCP is driven by selector events alone
        """Work that is not driven by selector events (pty open/close detection)."""

    @abstractmethod
    def drop_client(self) -> None:
        """Close the current client's connection (the fault --disconnect-every); keep listening."""

    @abstractmethod
    def close(self) -> None:
        """Close the client and the port."""


REPLACED_NOTICE_WAIT_S = 1.0
LINGER_S = 5.0  # a replaced client's close is awaited this long before ours


class TcpTransport(Transport):
    """Listens on HOST:PORT; a new connection replaces the current one (a dead or forgotten client)."""

    def __init__(self, selector: selectors.BaseSelector, host: str, port: int) -> None:
        super().__init__(selector)
        try:
            self.listener = socket.create_server((host, port), reuse_port=False)
        except OSError as e:
            raise TransportError(f"cannot listen on {host}:{port}: {e.strerror or e}") from e
        self.listener.setblocking(False)
        bound_host, bound_port = self.listener.getsockname()[:2]
        self.address = f"tcp://{bound_host}:{bound_port}"
        self.client: socket.socket | None = None
        selector.register(self.listener, selectors.EVENT_READ, self._accept)

    @property
    def connected(self) -> bool:
        return self.client is not None

    def _accept(self, _mask: int) -> None:
        try:
            sock, _ = self.listener.accept()
        except OSError:
            return
        if self.client is not None:  # say why before closing: the old ground then stops instead of fighting back
            self._tell_replaced(self.client)
        self.drop_client()
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        limit_unsent(sock)
        self.client = sock
        self.selector.register(sock, selectors.EVENT_READ, self._ready)
        self.on_connect()

    def _tell_replaced(self, old: socket.socket) -> None:
        tell_replaced(old, self.on_replaced())

    def _ready(self, mask: int) -> None:
        if mask & selectors.EVENT_READ:
            try:
                data = self.client.recv(READ_BYTES) if self.client else b""
            except (BlockingIOError, InterruptedError):
                return
            except OSError:
                data = b""
            if not data:
                self.drop_client()
                return
            self.on_data(data)
        if mask & selectors.EVENT_WRITE:
            self.flush()

    def flush(self) -> None:
        client = self.client
        if client is None or not self.outbuf:
            return
        data = self._sendable()
        try:
            sent = client.send(data) if data else 0
        except (BlockingIOError, InterruptedError):
            sent = 0
        except OSError:
            self.drop_client()
            return
        want = self._sent(len(data), sent)
        if self.selector.get_key(client).events != want:
            self.selector.modify(client, want, self._ready)

    def drop_client(self) -> None:
        client = self.client
        if client is None:
            return
        self.client = None
        self.outbuf.clear()
        self.selector.unregister(client)
        client.close()
        self.on_disconnect()

    def close(self) -> None:
        self.drop_client()
        self.selector.unregister(self.listener)
        self.listener.close()


class PtyTransport(Transport):
    """A pseudo-terminal in raw mode; a client has it open while the master does not see a hang-up."""

    def __init__(self, selector: selectors.BaseSelector) -> None:
        super().__init__(selector)
        try:
            self.master, slave = os.openpty()
            tty.setraw(slave)
            self.address = os.ttyname(slave)
        except OSError as e:
            raise TransportError(f"cannot create a pseudo-terminal: {e}") from e
        # Closing our slave end lets the master see POLLHUP until a client opens the device.
        os.close(slave)
        os.set_blocking(self.master, False)
        self._hup = select.poll()
        self._hup.register(self.master, select.POLLIN)
        self._open = False

    @property
    def connected(self) -> bool:
        return self._open

    def poll(self) -> None:
        if not self._open and not any(ev & select.POLLHUP for _, ev in self._hup.poll(0)):
            self._open = True
            self.selector.register(self.master, selectors.EVENT_READ, self._ready)
            self.on_connect()

    def _tell_replaced(self, old: socket.socket) -> None:
        tell_replaced(old, self.on_replaced())

    def _ready(self, mask: int) -> None:
        if mask & selectors.EVENT_READ:
            try:
                data = os.read(self.master, READ_BYTES)
            except BlockingIOError:
                data = None
            except OSError:  # EIO: the client closed the device
                self.drop_client()
                return
            if data:
                self.on_data(data)
        if mask & selectors.EVENT_WRITE:
            self.flush()

    def flush(self) -> None:
        if not self._open or not self.outbuf:
            return
        data = self._sendable()
        try:
            sent = os.write(self.master, data) if data else 0
        except BlockingIOError:
            sent = 0
        except OSError as e:
            if e.errno == errno.EIO:
                self.drop_client()
                return
            raise
        want = self._sent(len(data), sent)
        if self.selector.get_key(self.master).events != want:
            self.selector.modify(self.master, want, self._ready)

    def drop_client(self) -> None:
        # A pty cannot be closed from this side without losing its path: a forced disconnect only
        # forgets the session (the next bytes from the client are a new link, answered with HELLO).
        if not self._open:
            return
        self._open = False
        self.outbuf.clear()
        self.selector.unregister(self.master)
        self.on_disconnect()

    def close(self) -> None:
        if self._open:
            self.selector.unregister(self.master)
            self._open = False
        os.close(self.master)
