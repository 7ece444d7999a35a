"""What `dive run` says while it waits: a virtual agent that is silent for a while is compiling, and is said so."""

from __future__ import annotations

import io
import time

import pytest
from rich.console import Console

from groundstation.cli import progress as run_progress
from groundstation.cli.progress import RunDisplay
from groundstation.run.job import RunStatus


def _display(monkeypatch: pytest.MonkeyPatch) -> tuple[io.StringIO, RunDisplay]:
    monkeypatch.setattr(run_progress, "SLOW_START_S", 0.05)
    text = io.StringIO()
    return text, RunDisplay(Console(file=text, width=200), 2, "connecting to sim://", virtual=True)


def test_a_silent_virtual_agent_is_said_to_be_compiling(monkeypatch: pytest.MonkeyPatch) -> None:
    text, display = _display(monkeypatch)
    with display:
        time.sleep(0.5)
    assert text.getvalue().splitlines() == ["connecting to sim://", run_progress.SLOW_START_NOTE]


def test_an_agent_that_answers_at_once_gets_no_such_note(monkeypatch: pytest.MonkeyPatch) -> None:
    text, display = _display(monkeypatch)
    with display:
        display.show(RunStatus(link_up=True))
        time.sleep(0.5)
        display.show(RunStatus(link_up=True, episodes=1, ends=[(1, "success", 300.0)], successes=1))
    assert run_progress.SLOW_START_NOTE not in text.getvalue()
    assert "episode 1 of 2: success after 300.0 s (1 ok so far)" in text.getvalue()


class _GrowingWhileRead(list[tuple[int, str, float]]):
    """status.ends as the reader thread fills it: the next episode ends while the display reads the list."""

    def __getitem__(self, index):  # type: ignore[no-untyped-def]
        item = super().__getitem__(index)
        if len(self) < 3:
            self.append((len(self) + 1, "failure", 1.0))
        return item


def test_an_episode_that_ends_while_the_lines_are_printed_is_printed_next_time(
        monkeypatch: pytest.MonkeyPatch) -> None:
    text, display = _display(monkeypatch)
    status = RunStatus(link_up=True, ends=_GrowingWhileRead([(1, "success", 300.0)]))
    with display:
        display.show(status)
        display.show(status)
    said = [line.split(":")[0] for line in text.getvalue().splitlines() if line.startswith("episode")]
    assert said == ["episode 1 of 2", "episode 2 of 2", "episode 3 of 2"]
