"""TCP link (the ESP8266 Wi-Fi bridge, or the virtual agent): a plain socket with TCP_NODELAY."""

from __future__ import annotations

import select
import socket
from urllib.parse import urlsplit

from groundstation.errors import LinkError, LinkTimeout
from groundstation.links import Link

CONNECT_TIMEOUT_S = 3.0


def parse_host_port(url: str) -> tuple[str, int]:
    parts = urlsplit(url)
    try:
        port = parts.port
    except ValueError as e:
        raise LinkError(f"{url}: bad port ({e})") from e
    if not parts.hostname or port is None:
        raise LinkError(f"{url}: expected tcp://HOST:PORT")
    return parts.hostname, port


class TcpLink(Link):
    def __init__(self, url: str) -> None:
        super().__init__(url)
        self.host, self.port = parse_host_port(url)
        self._sock: socket.socket | None = None

    def _connect(self) -> None:
        try:
            sock = socket.create_connection((self.host, self.port), timeout=CONNECT_TIMEOUT_S)
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
