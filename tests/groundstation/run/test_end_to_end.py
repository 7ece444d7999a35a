"""The ground station against the real virtual agent (`python -m simulator serve`) over TCP and a pty."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.mcap_io import is_complete
from groundstation.recording.info import summarize
from groundstation.recording.recorder import RecorderConfig
from groundstation.run.job import RunConfig, run
from groundstation.session.agent_session import SessionConfig
from tests.groundstation.mcap_validation import validate_with_mcap_library

pytestmark = pytest.mark.slow
FAST = {"success_time_s": "5"}  # short episodes keep the suite quick


@pytest.fixture
def pty_agent() -> Iterator[str]:
    child = subprocess.Popen([sys.executable, "-m", "simulator", "serve", "--pty", "--speed", "max", "--seed", "5"],
                             stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout is not None
        device = child.stdout.readline().strip()
        assert device.startswith("/dev/"), device
        yield device
    finally:
        child.terminate()
        child.wait(10)


def test_dive_run_on_the_builtin_agent_records_every_message_valid(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["run", "--speed", "50", "--seed", "1", "--episodes", "3",
                                      "--success-time", "5", "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    path = Path(result.stdout.strip().splitlines()[-1])
    assert path.exists() and path.parent == tmp_path
    counts = validate_with_mcap_library(path)
    # three short episodes (5 s success time) plus the recovery between them: tens of samples at least
    assert counts["/agent/EPISODE_END"] >= 3 and counts["/agent/SAMPLE"] > 50
    info = CliRunner().invoke(app, ["log", "info", str(path), "--json"])
    summary = json.loads(info.stdout)
    assert summary["complete"] and len(summary["episodes"]) >= 3 and summary["samples_missing"] == 0
    assert summary["parameters"]["success_time_s"] == 5.0  # numbers as numbers (issue 14)
    assert summary["sessions"] == 1  # the agent's HELLO on connect and its answer to ours are one session


def test_over_a_pty_with_pyserial(tmp_path: Path, pty_agent: str) -> None:
    result = run(RunConfig(url=f"serial://{pty_agent}?baud=115200", episodes=2, params=FAST,
                           recorder=RecorderConfig(directory=tmp_path)))
    summary = summarize(result.paths[0])
    assert summary.complete and len(summary.episodes) >= 2 and summary.samples_missing == 0
    assert summary.sessions == 1


def test_reconnect_with_backfill_leaves_a_complete_recording(tmp_path: Path) -> None:
    url = "sim://?speed=20&seed=2&disconnect_every=8"
    result = run(RunConfig(url=url, episodes=6, params=FAST, recorder=RecorderConfig(directory=tmp_path),
                           session=SessionConfig(backoff_s=(0.05, 0.5))))
    summary = summarize(result.paths[0])
    assert summary.link_losses >= 1 and 2 <= summary.sessions <= summary.link_losses + 1
    assert summary.samples_backfilled > 0
    assert summary.samples_missing == 0 and result.still_missing == 0
    assert len(summary.episodes) >= 6


def test_kill_9_leaves_a_readable_file_that_recover_finishes(tmp_path: Path) -> None:
    env = {**os.environ, "DIVE_CACHE_DIR": str(tmp_path / "cache")}
    child = subprocess.Popen([sys.executable, "-m", "groundstation.cli.app", "run", "--speed", "5", "--seed", "3",
                              "--out", str(tmp_path)], env=env, stdout=subprocess.DEVNULL,
                             stderr=subprocess.DEVNULL, start_new_session=True)
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob("*.mcap")) and time.monotonic() < deadline:
            time.sleep(0.2)
        time.sleep(3.5)
        os.killpg(child.pid, signal.SIGKILL)  # dive and its simulator child
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
        child.wait(10)
    [path] = list(tmp_path.glob("*.mcap"))
    assert not is_complete(path)
    summary = summarize(path)
    assert summary.samples > 50 and summary.topics.get("/link", 0) >= 2  # at most ~1 s of data lost
    result = CliRunner().invoke(app, ["log", "recover", str(path)])
    assert result.exit_code == 0, result.output
    fixed = path.with_name(path.stem + "-recovered.mcap")
    assert is_complete(fixed) and validate_with_mcap_library(fixed)["/agent/SAMPLE"] == summary.samples
