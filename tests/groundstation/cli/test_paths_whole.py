"""No line that carries a path is ever broken (issue 37 item 4): a user copies the path from the line.

Every command that prints where it wrote (run, record, log info, log export, fit, study) runs as a user runs it, as
a child process, with a 40-column terminal (COLUMNS) and its files in a folder whose path is far longer than that,
as a CI machine's temporary folder can be. Each path it names must come out whole, on one line.
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import DIVE, dive_env, running

NARROW = "40"
LONG_NAME = "a-folder-whose-name-is-long-enough-to-wrap-" * 3


def _narrow_env(runtime: Path) -> dict[str, str]:
    return {**dive_env(runtime), "COLUMNS": NARROW, "PYTHONUNBUFFERED": "1"}


def _dive(runtime: Path, *args: str, timeout: float = 240.0) -> str:
    done = subprocess.run([*DIVE, *args], env=_narrow_env(runtime), capture_output=True, text=True, timeout=timeout)
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    assert "Traceback" not in done.stderr
    return done.stdout + done.stderr


def _whole(output: str, *paths: Path) -> None:
    """Each path appears whole on a line, and no line holds a piece of the long folder without all of it."""
    for path in paths:
        assert any(str(path) in line for line in output.splitlines()), f"{path} is not whole in:\n{output}"
    root = str(paths[0]).split(LONG_NAME)[0] + LONG_NAME
    for line in output.splitlines():
        if LONG_NAME[:20] in line or root[-20:] in line:
            assert root in line, f"a broken path: {line!r}\nin:\n{output}"


@pytest.mark.slow
def test_run_log_fit_and_study_print_their_paths_whole_on_a_narrow_terminal(tmp_path: Path) -> None:
    base = tmp_path / LONG_NAME
    runtime = tmp_path / "runtime"
    output = _dive(runtime, "run", "sim://?seed=3", "--speed", "max", "--episodes", "2", "--out", str(base / "run"))
    (recording,) = sorted((base / "run").glob("*.mcap"))
    _whole(output, recording)

    _whole(_dive(runtime, "log", "info", str(recording)), recording)
    _whole(_dive(runtime, "log", "info", str(base / "run")), recording)
    for form, written in (("csv", base / "samples.csv"), ("npz", base / "transitions.npz"),
                          ("parquet", base / "tables")):
        output = _dive(runtime, "log", "export", str(recording), "--format", form, "--out", str(written))
        assert written.exists()
        _whole(output, written)

    plant = base / "fit" / "plant.toml"
    output = _dive(runtime, "fit", str(recording), "--out", str(plant))
    assert plant.is_file()
    _whole(output, plant)

    study = base / "study"
    output = _dive(runtime, "study", "--trials", "1", "--episodes", "2", "--out", str(study))
    assert (study / "summary.json").is_file()
    _whole(output, study)


@pytest.mark.slow
def test_record_prints_its_path_whole_on_a_narrow_terminal(tmp_path: Path) -> None:
    base = tmp_path / LONG_NAME
    runtime = tmp_path / "runtime"
    agent = FakeAgent()
    try:
        with running(runtime, agent.url, base / "run") as run:
            second = subprocess.Popen([*DIVE, "record", "--out", str(base / "second")], env=_narrow_env(runtime),
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and not list((base / "second").glob("*.mcap")):
                time.sleep(0.05)
            time.sleep(0.5)
            second.send_signal(signal.SIGINT)
            out, err = second.communicate(timeout=30)
            run.send_signal(signal.SIGINT)
            run.communicate(timeout=30)
    finally:
        agent.close()
    assert "Traceback" not in err, err
    (recording,) = sorted((base / "second").glob("*.mcap"))
    _whole(out + err, recording)
    assert os.path.getsize(recording) > 0
