"""What `dive run` says while it waits: a virtual agent that is silent for a while is compiling, and is said so."""

from __future__ import annotations

import io
import time

import pytest
from rich.console import Console

from groundstation import run_progress
from groundstation.run_progress import RunDisplay
from groundstation.runner import RunStatus


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
