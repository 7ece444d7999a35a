"""The ground waits for a virtual agent that answers BUSY while its program builds (SPEC.md s. 4, a starting agent):
`dive check` passes, its answer-time check included, and `dive run` records, each saying in one line that it waits.

The build is made slow by the test hook $DIVE_SIM_BUILD_DELAY_S (the agent process inherits it), not by a cold compile
cache, which costs minutes.
"""

from __future__ import annotations

import contextlib
import os
import pty
import signal
import subprocess
import sys
from pathlib import Path

import pytest

from simulator.serve.build import BUILD_DELAY_ENV
from tests.groundstation.check_helpers import agent, by_result, check
from tests.reliability.recordings import DIVE_MAIN, ROOT, dive, read

BUILD_DELAY_S = "5"


def test_dive_check_waits_for_a_starting_agent_and_its_answer_times_pass(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(BUILD_DELAY_ENV, BUILD_DELAY_S)
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--seed", "3") as url:
        code, report = check(url, "--only", "handshake", "--only", "seq.agent_counter", "--only", "timesync",
                             "--only", "link.answer_time", "--timeout", "10")
    assert not by_result(report, "FAIL"), by_result(report, "FAIL")
    answer = next(c for c in report["checks"] if c["id"] == "link.answer_time")
    assert answer["result"] == "PASS" and "BUSY while starting" in answer["detail"], answer
    counter = next(c for c in report["checks"] if c["id"] == "seq.agent_counter")
    assert counter["result"] == "PASS"  # the hand-over from the starting agent lost no frame, doubled none
    assert code == 0


def test_dive_run_waits_for_a_starting_agent_in_one_line_and_records(tmp_path: Path) -> None:
    env = {**os.environ, BUILD_DELAY_ENV: BUILD_DELAY_S}
    done = dive("run", "sim://?speed=max&seed=3", "--episodes", "1", "--viewer", "none", "--out",
                str(tmp_path / "run.mcap"), env=env)
    assert done.returncode == 0, done.stderr
    waiting = [line for line in done.stderr.splitlines() if line.startswith("waiting: the agent answers BUSY")]
    assert len(waiting) == 1 and "building its program" in waiting[0], done.stderr  # not a terminal: said once
    assert "ALARM" not in done.stderr and "Traceback" not in done.stderr, done.stderr
    recording = read(tmp_path / "run.mcap")
    assert len(recording.episode_ends) >= 1
    busy = [e for e in recording.events if e.get("kind") == "agent_busy"]
    assert busy and busy[0]["data"]["command"] == "PARAM_LIST"  # the wait is in the recording, as it happened


def test_a_tool_on_a_terminal_shows_one_waiting_line_then_its_answer(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(BUILD_DELAY_ENV, BUILD_DELAY_S)
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--seed", "3") as url:
        master, slave = pty.openpty()  # dive's stdout and stderr: a real terminal, so rich draws its live line
        try:
            proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "params", url, "get", "gamma"], stdout=slave,
                                    stderr=slave, stdin=subprocess.DEVNULL, cwd=ROOT,
                                    env={**os.environ, "COLUMNS": "200"})
            os.close(slave)
            shown = b""
            with contextlib.suppress(OSError):  # EIO: the tool ended and closed the terminal
                while chunk := os.read(master, 65536):
                    shown += chunk
            assert proc.wait(60) == 0
        finally:
            os.close(master)
    text = shown.decode(errors="replace")
    assert "waiting: the agent answers BUSY (starting, building its program" in text, text
    assert "gamma" in text.rsplit("waiting:", 1)[-1], text  # the answer after the line


@pytest.mark.parametrize(("signum", "said"), [
    (signal.SIGTERM, "stopped by SIGTERM; nothing to stop: the agent was still starting"),
    (signal.SIGINT, "stopped by Ctrl-C; nothing to stop: the run had not set the agent going"),
], ids=["SIGTERM", "SIGINT"])
def test_a_signal_while_the_agent_starts_stops_dive_run_at_once(tmp_path: Path, signum: int, said: str) -> None:
    """The wait for a BUSY agent ends with the run's stop: not minutes later, when the agent has built its program;
    the recording is named as after any other stop."""
    env = {**os.environ, BUILD_DELAY_ENV: "120"}
    proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "run", "sim://?speed=max&seed=3", "--viewer", "none",
                             "--out", str(tmp_path / "run.mcap")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, cwd=ROOT, env=env)
    assert proc.stderr is not None
    for line in proc.stderr:  # until the run says it waits
        if line.startswith("waiting: the agent answers BUSY"):
            break
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=30)
    assert proc.returncode == 130, err
    assert said in err and "Traceback" not in err, err
    assert out.splitlines() == [str(tmp_path / "run.mcap")], out  # the file is named, as after any other stop
    assert (tmp_path / "run.mcap").stat().st_size > 0
