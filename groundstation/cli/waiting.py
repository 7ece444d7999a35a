"""One line while the agent answers BUSY (a virtual agent building its program): waiting, with the time waited.

On a terminal it is one line redrawn in place (rich), gone once the agent answers; elsewhere (a log, CI) a line at
the first BUSY and one every PLAIN_EVERY_S after it. Used as a session listener by the tools (cli/common.py) and
through `say` by `dive run` and `dive check`, which have a live line of their own.
"""

from __future__ import annotations

import threading
import time
from types import TracebackType

from rich.console import Console
from rich.progress import Progress, SpinnerColumn, TaskID, TextColumn, TimeElapsedColumn

from groundstation.safe_output import in_markup, styled
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import AckResult
from protocol import messages as m

PLAIN_EVERY_S = 30.0


def busy_text(reason: str) -> str:
    """What the line says: the agent's own reason (how far its build got) is data, shown as it came."""
    return f"waiting: the agent answers BUSY ({reason or 'no reason given'})"


class BusyLine:
    """A session listener; a context manager that removes its line at exit."""

    def __init__(self, console: Console) -> None:
        self.console = console
        self._lock = threading.Lock()
        self._progress: Progress | None = None
        self._task: TaskID | None = None
        self._next_plain_s = 0.0

    def say(self, reason: str) -> None:
        """Show (or redraw) the line for a BUSY whose reason is `reason`."""
        text = busy_text(reason)
        with self._lock:
            if not self.console.is_terminal:
                now = time.monotonic()
                if now >= self._next_plain_s:
                    self._next_plain_s = now + PLAIN_EVERY_S
                    self.console.print(styled(text, "dim"), soft_wrap=True)
                return
            if self._progress is None:
                self._progress = Progress(SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(),
                                          console=self.console, transient=True)
                self._progress.start()
                self._task = self._progress.add_task(in_markup(text), total=None)
            else:
                assert self._task is not None
                self._progress.update(self._task, description=in_markup(text))

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.AGENT_BUSY:
            self.say(event.detail)

    def on_received(self, received: Received) -> None:
        message = received.message
        if self._progress is not None and isinstance(message, m.Ack) and message.result != AckResult.BUSY:
            self.close()  # a command got through: the agent is ready

    def on_sent(self, sent: Sent) -> None:
        pass

    def close(self) -> None:
        with self._lock:
            if self._progress is not None:
                self._progress.stop()
                self._progress = None

    def __enter__(self) -> BusyLine:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()
