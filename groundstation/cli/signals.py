"""SIGTERM and SIGHUP end `dive run` as Ctrl-C does (issue 13 item 3): CMD_STOP, the footer, the path printed, the
virtual agent stopped. Python's default for both is to die at once, leaving a file without a footer, a real agent
learning, and a sim:// child holding its port."""

from __future__ import annotations

import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType

STOP_SIGNALS = (signal.SIGTERM, signal.SIGHUP)


@contextmanager
def stop_on_signals(stop: threading.Event, received: list[str]) -> Iterator[None]:
    """While inside: the first SIGTERM/SIGHUP sets `stop` (the run winds down cleanly) and is named in `received`;
    a second one raises KeyboardInterrupt (as a second Ctrl-C would). Outside, the previous handlers are back."""

    def handler(signum: int, _frame: FrameType | None) -> None:
        if stop.is_set():
            raise KeyboardInterrupt
        received.append(signal.Signals(signum).name)
        stop.set()

    if threading.current_thread() is not threading.main_thread():  # signals are the main thread's alone
        yield
        return
    previous = {sig: signal.signal(sig, handler) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)
