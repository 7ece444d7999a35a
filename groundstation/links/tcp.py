"""TCP link (the ESP8266 Wi-Fi bridge, or the virtual agent): a plain socket with TCP_NODELAY."""

from __future__ import annotations

import select
import socket

from groundstation.errors import LinkError, LinkTimeout
from groundstation.links import Link, split_url

CONNECT_TIMEOUT_S = 3.0
# A small, fixed receive buffer (set before connecting, so the kernel does not autotune it to megabytes): when the
# ground falls behind a fast sender (the virtual agent at --speed max), the backlog stays at the sender, which then
# waits, instead of piling up here where every command's ACK would queue behind it. Linux doubles it (4.5 KiB, ~0.4 s
# of a 115200-baud link), still far above what the agent sends per round trip over Wi-Fi. At --speed max, 2 KiB
# against 8 KiB halved the round trip (19 ms against 41 ms median, benchmarks/link_latency_bench.py, load 1.4-3)
# and left the served agent's speed within run-to-run noise (benchmarks/sim_speed_bench.py).
RECEIVE_BUFFER_BYTES = 2 * 1024


def parse_host_port(url: str) -> tuple[str, int]:
    parts = split_url(url)
    port = parts.port
    if not parts.hostname or port is None:
        raise LinkError(f"{url}: expected tcp://HOST:PORT")
    return parts.hostname, port


def _connect(host: str, port: int, receive_buffer_bytes: int) -> socket.socket:
    """socket.create_connection, with the receive buffer set before the handshake (it fixes the window scale)."""
    error: OSError | None = None
    for family, kind, proto, _, address in socket.getaddrinfo(host, port, type=socket.SOCK_STREAM):
        sock = socket.socket(family, kind, proto)
        try:
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer_bytes)
            sock.settimeout(CONNECT_TIMEOUT_S)
            sock.connect(address)
            return sock
        except OSError as e:
            sock.close()
            error = e
    raise error if error is not None else OSError(f"cannot resolve {host}")


class TcpLink(Link):
    def __init__(self, url: str, receive_buffer_bytes: int = RECEIVE_BUFFER_BYTES) -> None:
        super().__init__(url)
        self.host, self.port = parse_host_port(url)
        self.receive_buffer_bytes = receive_buffer_bytes
        self._sock: socket.socket | None = None

    def _connect(self) -> None:
        try:
            sock = _connect(self.host, self.port, self.receive_buffer_bytes)
        except TimeoutError as e:
            raise LinkTimeout(f"{self.url}: no answer within {CONNECT_TIMEOUT_S:.0f} s") from e
        except OSError as e:
            raise LinkError(f"{self.url}: cannot connect ({e.strerror or e})") from e
        # Small frames must leave at once: Nagle would add up to 200 ms to every command's round trip.
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        sock.setblocking(False)
        self._sock = sock

    def _disconnect(self) -> None:
        sock, self._sock = self._sock, None
        if sock is not None:
            try:
                sock.close()
            except OSError:
                pass

    def _socket(self) -> socket.socket:
        if self._sock is None:
            raise LinkError(f"{self.url}: not connected")
        return self._sock

    def _read(self, timeout_s: float) -> bytes:
        sock = self._socket()
        try:
            ready, _, _ = select.select([sock], [], [], timeout_s)
            if not ready:
                return b""
            data = sock.recv(65536)
        except BlockingIOError:
            return b""
        except (OSError, ValueError) as e:
            raise LinkError(f"{self.url}: receive failed ({e})") from e
        if not data:
            raise LinkError(f"{self.url}: connection closed by the agent")
        return data

    def _write(self, data: bytes) -> None:
        sock = self._socket()
        view = memoryview(data)
        try:
            while view:
                try:
                    sent = sock.send(view)
                except BlockingIOError:
                    select.select([], [sock], [], 1.0)
                    continue
                view = view[sent:]
        except (OSError, ValueError) as e:
            raise LinkError(f"{self.url}: send failed ({e})") from e
