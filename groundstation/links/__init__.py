"""Links by URL: one transport interface, backends picked from a registry and imported lazily."""

from __future__ import annotations

import importlib
import os
import threading
import time
from abc import ABC, abstractmethod
from types import TracebackType
from typing import Self
from urllib.parse import SplitResult, urlsplit

from groundstation.errors import BadUrlError, LinkError, UnknownSchemeError

DEFAULT_URL = "sim://"
# scheme -> "module:Class"; imported only when a URL with that scheme is opened (pyserial, subprocess...)
_BACKENDS: dict[str, str] = {
    "tcp": "groundstation.links.tcp:TcpLink",
    "hub": "groundstation.links.hub:HubLink",
    "sim": "groundstation.links.sim:SimLink",
    "serial": "groundstation.links.serial_port:SerialLink",
    "socket": "groundstation.links.serial_port:SerialLink",
    "loop": "groundstation.links.serial_port:SerialLink",
    "rfc2217": "groundstation.links.serial_port:SerialLink",
    "spy": "groundstation.links.serial_port:SerialLink",
    "hwgrep": "groundstation.links.serial_port:SerialLink",
    "memory": "groundstation.links.memory:MemoryLink",
}


class Link(ABC):
    """A byte stream to the agent. Subclasses do raw I/O; the public recv() owns the timeout.

    Life cycle: open() -> recv()/send() ... -> reconnect() after a failure -> close(). close() is final
    (a simulator child is stopped); reconnect() re-establishes the byte stream to the same peer.
    """

    def __init__(self, url: str) -> None:
        self.url = url
        self._open = False
        self._write_lock = threading.Lock()

    # ------------------------------------------------------------------ for subclasses
    @abstractmethod
    def _connect(self) -> None:
        """Establish the byte stream; raise LinkError with a clear message."""

    @abstractmethod
    def _disconnect(self) -> None:
        """Drop the byte stream (must not raise)."""

    @abstractmethod
    def _read(self, timeout_s: float) -> bytes:
        """Wait at most timeout_s for bytes; b"" on timeout; raise LinkError when the stream is gone."""

    @abstractmethod
    def _write(self, data: bytes) -> None:
        """Write all of data; raise LinkError when the stream is gone."""

    def _release(self) -> None:  # noqa: B027 optional hook
        """Free what outlives reconnects (a child process); called once by close()."""

    # ------------------------------------------------------------------ public
    @property
    def is_open(self) -> bool:
        return self._open

    def open(self) -> Self:
        if not self._open:
            self._connect()
            self._open = True
        return self

    def recv(self, timeout_s: float | None = None) -> bytes:
        """Bytes received, waiting at most timeout_s (None = until some arrive); b"" on timeout."""
        if not self._open:
            raise LinkError(f"{self.url}: link is not open")
        deadline = None if timeout_s is None else time.monotonic() + timeout_s
        while True:
            remaining = 0.5 if deadline is None else max(0.0, deadline - time.monotonic())
            data = self._read(remaining)
            if data or (deadline is not None and time.monotonic() >= deadline):
                return data

    def send(self, data: bytes) -> None:
        if not self._open:
            raise LinkError(f"{self.url}: link is not open")
        with self._write_lock:
            self._write(data)

    def drop(self) -> None:
        """Drop a failed byte stream (never raises); reconnect() brings it back."""
        self._open = False
        try:
            self._disconnect()
        except Exception:  # noqa: BLE001 a dead stream may fail to close in any way
            pass

    def reconnect(self) -> None:
        """Drop and re-establish the byte stream to the same peer."""
        self._open = False
        self._disconnect()
        self._connect()
        self._open = True

    def close(self) -> None:
        self._open = False
        self._disconnect()
        self._release()

    def __enter__(self) -> Self:
        return self.open()

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.url!r})"


def default_url() -> str:
    """$DIVE_URL, else the built-in virtual agent."""
    return os.environ.get("DIVE_URL") or DEFAULT_URL


def split_url(url: str) -> SplitResult:
    """urlsplit, its port read too: a URL it cannot read is one BadUrlError (exit 2), not a ValueError from deep in
    a command (issue 38 N7: `tcp://127.0.0.1:99999`, `tcp://[::1`)."""
    try:
        parts = urlsplit(url)
        parts.port  # noqa: B018 read for its check: out of range raises here
    except ValueError as e:
        raise BadUrlError(f"bad link URL {url!r}: {e}") from None
    return parts


def link_class(url: str) -> type[Link]:
    scheme = split_url(url).scheme.lower() if "://" in url else ""
    if url.startswith("/dev/"):
        scheme = "serial"
    target = _BACKENDS.get(scheme)
    if target is None:
        known = ", ".join(f"{s}://" for s in _BACKENDS if s not in ("spy", "hwgrep", "memory"))
        raise UnknownSchemeError(f"unknown link URL {url!r}: use one of {known}")
    module_name, class_name = target.split(":")
    cls: type[Link] = getattr(importlib.import_module(module_name), class_name)
    return cls


def make_link(url: str | None = None) -> Link:
    """The link for a URL, not yet opened (None = default_url())."""
    url = url or default_url()
    return link_class(url)(url)


def open_link(url: str | None = None) -> Link:
    """The link for a URL, opened."""
    return make_link(url).open()
