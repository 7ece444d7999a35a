"""The run pane's key: `a` acknowledges the alarms, as `dive ack` does from another pane.

The terminal is put in cbreak mode (no line buffering, no echo) only while the run shows its live status line and
only when the run is the terminal's foreground job: a `dive run &` touching the terminal would be stopped by
SIGTTOU. Ctrl-C still interrupts (cbreak keeps ISIG). The mode is restored however the run ends.
"""

from __future__ import annotations

import contextlib
import os
import select
import sys
import threading
from types import TracebackType
from typing import Any, TextIO

ACK_KEYS = frozenset("aA")


class AckKey:
    """A context manager: while it is open, the key `a` on `stream` sets `ack` (the run acknowledges then)."""

    def __init__(self, ack: threading.Event, stream: TextIO | None = None) -> None:
        self.ack = ack
        self.stream = stream if stream is not None else sys.stdin
        self._saved: list[Any] | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    @property
    def active(self) -> bool:
        """Whether the key is read (a terminal the run owns)."""
        return self._saved is not None

    def __enter__(self) -> AckKey:
        try:
            import termios
            import tty

            fd = self.stream.fileno()
            if not os.isatty(fd) or os.tcgetpgrp(fd) != os.getpgrp():
                return self
            self._saved = termios.tcgetattr(fd)
            tty.setcbreak(fd, termios.TCSANOW)
        except (ImportError, OSError, ValueError):  # no termios (Windows), a closed or odd stdin: no key, no harm
            self._saved = None
            return self
        self._thread = threading.Thread(target=self._read, args=(fd,), name="dive-run-keys", daemon=True)
        self._thread.start()
        return self

    def _read(self, fd: int) -> None:
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([fd], [], [], 0.2)
                if not ready:
                    continue
                typed = os.read(fd, 64).decode(errors="ignore")
            except OSError:
                return
            if not typed:
                return  # the terminal is gone
            if ACK_KEYS & set(typed):
                self.ack.set()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join(1.0)
        if self._saved is not None:
            import termios

            with contextlib.suppress(OSError, termios.error):
                termios.tcsetattr(self.stream.fileno(), termios.TCSADRAIN, self._saved)
            self._saved = None
