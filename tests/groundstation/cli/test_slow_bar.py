"""The bar of long `dive log` work (issue 28): on a terminal (a real pseudo-terminal here) it appears once the work
has taken SHOW_AFTER_S, even inside one long step with no update; quick work and a pipe get none."""

from __future__ import annotations

import os
import pty
import sys
import time

import pytest

from groundstation.cli.bar import SlowBar


def _on_a_terminal(monkeypatch: pytest.MonkeyPatch, work_s: float, show_after_s: float) -> str:
    master, slave = pty.openpty()
    terminal = os.fdopen(slave, "w", buffering=1)
    monkeypatch.setattr(sys, "stderr", terminal)
    try:
        with SlowBar("summarising 3 file(s)", show_after_s=show_after_s) as bar:
            bar.update(1, 3)
            time.sleep(work_s)  # one long step: no update comes
        terminal.flush()
        os.set_blocking(master, False)
        try:
            return os.read(master, 65536).decode(errors="replace")
        except BlockingIOError:
            return ""
    finally:
        terminal.close()
        os.close(master)


def test_long_work_shows_a_bar_without_updates(monkeypatch: pytest.MonkeyPatch) -> None:
    assert "summarising 3 file(s)" in _on_a_terminal(monkeypatch, work_s=0.6, show_after_s=0.1)


def test_quick_work_shows_nothing(monkeypatch: pytest.MonkeyPatch) -> None:
    assert _on_a_terminal(monkeypatch, work_s=0.0, show_after_s=1.0) == ""


def test_not_a_terminal_shows_nothing(capfd: pytest.CaptureFixture[str]) -> None:
    with SlowBar("exporting", show_after_s=0.0) as bar:
        bar.update(1, 2)
        time.sleep(0.2)
    assert capfd.readouterr().err == ""
