"""The operator's controls on a tank day: a real `dive run` on the virtual agent, its hub, and the tools as processes.

Start, pause, go to another depth, resume, an emergency surface, start again: all without restarting the run,
each answered with the agent's ACK and its mode, a refusal saying what to do instead.
"""

from __future__ import annotations

import re
import signal
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from tests.groundstation.run.test_hub import DIVE, _env, _one_line_failure, dive

pytestmark = pytest.mark.slow
SIM = "sim://?speed=20&seed=4"


@contextmanager
def running(runtime: Path, url: str, out: Path, *options: str) -> Iterator[subprocess.Popen[str]]:
    """`dive run URL OPTIONS` until the block ends with a Ctrl-C (SIGINT); its hub announced before the block."""
    proc = subprocess.Popen([*DIVE, "run", url, "--out", str(out), *options], env=_env(runtime),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120  # a first start compiles the simulator
        while time.monotonic() < deadline and proc.poll() is None and not list(runtime.glob("runs/*.json")):
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
        yield proc
    finally:
        if proc.poll() is None:
            proc.send_signal(signal.SIGINT)
        try:
            proc.wait(30)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def _mode(runtime: Path) -> str:
    done = dive(runtime, "status")
    assert done.returncode == 0, done.stderr
    found = re.search(r"^mode (\w+),", done.stdout, re.MULTILINE)
    assert found is not None, done.stdout
    return found.group(1)


def _until_mode(runtime: Path, wanted: set[str], timeout_s: float = 60.0) -> str:
    deadline = time.monotonic() + timeout_s
    while True:
        mode = _mode(runtime)
        if mode in wanted or time.monotonic() > deadline:
            return mode
        time.sleep(0.5)


def test_a_tank_day_from_the_command_line_without_restarting_the_run(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    with running(runtime, SIM, tmp_path / "rec", "--success-time", "5") as run:
        assert _until_mode(runtime, {"LEARNING"}) == "LEARNING"
        # hover while learning: refused by the agent, and the line says what to do
        _one_line_failure(dive(runtime, "hover", "0.3"), "surface first: dive surface")
        paused = dive(runtime, "pause")
        assert paused.returncode == 0 and "CMD_PAUSE accepted" in paused.stdout, paused.stderr
        assert "the agent is PAUSED" in paused.stdout
        moved = dive(runtime, "target", "0.5")
        assert moved.returncode == 0 and "CMD_SET_TARGET accepted" in moved.stdout, moved.stderr
        resumed = dive(runtime, "resume")
        assert resumed.returncode == 0 and "CMD_START accepted" in resumed.stdout, resumed.stderr
        assert re.search(r"the agent is (RECOVERING|LEARNING)", resumed.stdout), resumed.stdout
        _one_line_failure(dive(runtime, "resume"), "not paused: dive start starts learning")
        surfaced = dive(runtime, "surface")
        assert surfaced.returncode == 0 and "surfacing (hub://" in surfaced.stdout, surfaced.stderr
        _until_mode(runtime, {"IDLE"})
        time.sleep(1.0)  # the run would have started it again by now if it ignored the operator
        assert _mode(runtime) == "IDLE"
        # not on a terminal: reset-model needs --yes, and nothing is sent without it
        _one_line_failure(dive(runtime, "reset-model"), "add --yes", code=2)
        reset = dive(runtime, "reset-model", "--yes")
        assert reset.returncode == 0 and "CMD_RESET_MODEL accepted" in reset.stdout, reset.stderr
        assert "the agent is IDLE" in reset.stdout
        started = dive(runtime, "start")
        assert started.returncode == 0 and "CMD_START accepted" in started.stdout, started.stderr
        assert _until_mode(runtime, {"LEARNING"}) == "LEARNING"
        time.sleep(3.0)  # an episode or so of the handed-back run
    _, err = run.communicate()
    assert run.returncode == 130, err
    said = err.splitlines()
    assert any("the operator paused learning" in line and "dive resume" in line for line in said), err
    assert any("took over (CMD_SURFACE" in line and "dive start" in line for line in said), err
    assert sum("handed the agent back" in line for line in said) == 2, err  # the resume and the start
    [recording] = sorted((tmp_path / "rec").glob("*.mcap"))
    commands = ["/ground/CMD_PAUSE", "/ground/CMD_SET_TARGET", "/ground/CMD_START", "/ground/CMD_SURFACE",
                "/ground/CMD_HOVER", "/ground/CMD_RESET_MODEL"]
    contents = read_recording(recording, {*commands, "/agent/EPISODE_END"})
    topics = [m.topic for m in contents.messages]
    assert topics.count("/ground/CMD_START") == 3  # the run's own, the resume and the start
    assert topics.count("/ground/CMD_RESET_MODEL") == 1  # only the one with --yes reached the agent
    last_start = max(i for i, topic in enumerate(topics) if topic == "/ground/CMD_START")
    assert "/agent/EPISODE_END" in topics[last_start:]  # the handed-back run learns and records on
    assert [m.json()["target_depth_m"] for m in contents.messages if m.topic == "/ground/CMD_SET_TARGET"] == \
        [pytest.approx(0.5)]


def test_a_depth_out_of_range_is_refused_before_anything_is_sent(tmp_path: Path) -> None:
    done = subprocess.run([*DIVE, "target", "7"], env=_env(tmp_path), capture_output=True, text=True, timeout=30)
    _one_line_failure(done, "target depth 7 m is outside [0.05, 2.5] m")
