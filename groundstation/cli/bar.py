"""A progress bar on stderr for long work: shown on a terminal once the work has taken a second, never in a pipe."""

from __future__ import annotations

import sys
import time
from types import TracebackType

from rich.console import Console
from rich.progress import (
    BarColumn,
    DownloadColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from groundstation.safe_output import in_markup

SHOW_AFTER_S = 1.0  # quicker work finishes before a bar could say anything


class SlowBar:
    """`update(done, total)` as the work goes; a bar appears (transient) only if the work is still going after
    SHOW_AFTER_S and stderr is a terminal. `unit` "bytes" shows MB, anything else a count."""

    def __init__(self, description: str, unit: str = "bytes", show_after_s: float = SHOW_AFTER_S) -> None:
        self._description = in_markup(description)
        self._unit = unit
        self._show_at = time.monotonic() + show_after_s
        self._progress: Progress | None = None
        self._task: object = None
        self._live = sys.stderr.isatty()

    def __enter__(self) -> SlowBar:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if self._progress is not None:
            self._progress.__exit__(exc_type, exc, tb)

    def update(self, done: int, total: int | None = None, description: str | None = None) -> None:
        if self._progress is None:
            if not self._live or time.monotonic() < self._show_at:
                return
            amount = DownloadColumn() if self._unit == "bytes" else MofNCompleteColumn()
            self._progress = Progress(TextColumn("{task.description}"), BarColumn(), amount, TimeElapsedColumn(),
                                      TimeRemainingColumn(), transient=True,
                                      console=_stderr_console())
            self._progress.__enter__()
            self._task = self._progress.add_task(self._description, total=total)
        self._progress.update(self._task, completed=done, total=total,  # type: ignore[arg-type]
                              description=in_markup(description) if description else self._description)


def _stderr_console() -> Console:
    return Console(stderr=True)
