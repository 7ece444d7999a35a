"""Serial links through pyserial: serial:///dev/ttyUSB0?baud=115200 and pyserial URLs (socket://, loop://...).

The only module of the ground station that imports `serial`.
"""

from __future__ import annotations

from urllib.parse import parse_qs, urlsplit

import serial

from groundstation.errors import LinkError
from groundstation.links import Link

DEFAULT_BAUD = 115200


def serial_target(url: str) -> tuple[str, int]:
    """(what pyserial opens, baud rate) for a serial:// URL, a bare /dev path or a pyserial URL."""
    if url.startswith("/dev/"):
        return url, DEFAULT_BAUD
    parts = urlsplit(url)
    query = parse_qs(parts.query)
    try:
        baud = int(query.get("baud", [str(DEFAULT_BAUD)])[0])
    except ValueError as e:
        raise LinkError(f"{url}: baud must be an integer") from e
    if parts.scheme == "serial":
        device = parts.path or parts.netloc
        if not device:
            raise LinkError(f"{url}: expected serial:///dev/DEVICE?baud=N")
        return device, baud
    return url, baud  # a pyserial URL handler (socket://, loop://, rfc2217://) takes the whole URL


class SerialLink(Link):
    def __init__(self, url: str) -> None:
        super().__init__(url)
        self.port, self.baud = serial_target(url)
        self._serial: serial.SerialBase | None = None

    def _connect(self) -> None:
        try:
            self._serial = serial.serial_for_url(self.port, baudrate=self.baud, timeout=0, write_timeout=2.0)
        except (serial.SerialException, OSError, ValueError) as e:
            raise LinkError(f"{self.url}: cannot open {self.port} ({e})") from e

    def _disconnect(self) -> None:
        port, self._serial = self._serial, None
        if port is not None:
            try:
                port.close()
            except (serial.SerialException, OSError):
                pass

    def _port(self) -> serial.SerialBase:
        if self._serial is None:
            raise LinkError(f"{self.url}: not open")
        return self._serial

    def _read(self, timeout_s: float) -> bytes:
        port = self._port()
        try:
            port.timeout = timeout_s
            first = port.read(1)
            if not first:
                return b""
            waiting = port.in_waiting
            return bytes(first + (port.read(waiting) if waiting else b""))
        except (serial.SerialException, OSError, TypeError, AttributeError) as e:
            raise LinkError(f"{self.url}: read failed ({e})") from e

    def _write(self, data: bytes) -> None:
        try:
            self._port().write(data)
        except (serial.SerialException, OSError) as e:
            raise LinkError(f"{self.url}: write failed ({e})") from e
