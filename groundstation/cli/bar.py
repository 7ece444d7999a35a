"""A progress bar on stderr for long work: shown on a terminal once the work has taken a second, never in a pipe."""

from __future__ import annotations

import sys
import threading
from types import TracebackType

from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from groundstation.safe_output import in_markup

SHOW_AFTER_S = 1.0  # quicker work finishes before a bar could say anything


class SlowBar:
    """`update(done, total)` as the work goes; a bar appears (transient) if the work is still going after
    SHOW_AFTER_S and stderr is a terminal, even when no update comes meanwhile (one long step: its elapsed time
    shows it is alive). `unit` "bytes" shows MB, anything else a count."""

    def __init__(self, description: str, unit: str = "bytes", show_after_s: float = SHOW_AFTER_S) -> None:
        self._description = in_markup(description)
        self._unit = unit
        self._show_after_s = show_after_s
        self._progress: Progress | None = None
        self._task: object = None
        self._state: tuple[int, int | None] = (0, None)
        self._lock = threading.Lock()
        self._timer: threading.Timer | None = None

    def __enter__(self) -> SlowBar:
        if sys.stderr.isatty():
            self._timer = threading.Timer(self._show_after_s, self._show)
            self._timer.daemon = True
            self._timer.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        with self._lock:
            if self._timer is not None:
                self._timer.cancel()
            if self._progress is not None:
                self._progress.__exit__(exc_type, exc, tb)
                self._progress = None
            self._timer = None

    def _show(self) -> None:
        with self._lock:
            if self._timer is None or self._progress is not None:
                return
            amount = DownloadColumn() if self._unit == "bytes" else MofNCompleteColumn()
            self._progress = Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), amount,
                                      TimeElapsedColumn(), TimeRemainingColumn(), transient=True,
                                      console=Console(stderr=True))
            self._progress.__enter__()
            done, total = self._state
            self._task = self._progress.add_task(self._description, total=total, completed=done)

    def update(self, done: int, total: int | None = None, description: str | None = None) -> None:
        with self._lock:
            self._state = (done, total)
            if description:
                self._description = in_markup(description)
            if self._progress is not None:
                self._progress.update(self._task, completed=done, total=total,  # type: ignore[arg-type]
                                      description=self._description)
