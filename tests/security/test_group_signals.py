"""A signal to `dive run sim://`'s whole process group (Ctrl-C in a terminal, `timeout`, systemd) ends it with 130 and
the file name, whatever the signal reaches first (issue 25 L1): the virtual agent is not killed under the run."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from groundstation.recording.info import summarize

pytestmark = pytest.mark.slow  # the virtual agent's start


@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_signal_to_the_process_group_ends_the_run_with_130_and_the_file(tmp_path: Path, signum: int) -> None:
    env = {**os.environ, "DIVE_CACHE_DIR": str(tmp_path / "cache"), "DIVE_RUNTIME_DIR": str(tmp_path / "rt")}
    child = subprocess.Popen([sys.executable, "-m", "groundstation.cli.app", "run", "sim://?speed=5&seed=3", "--out",
                              str(tmp_path)], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                             start_new_session=True)  # its own group, as a shell job's
    try:
        deadline = time.monotonic() + 120
        while not list(tmp_path.glob("*.mcap")) and time.monotonic() < deadline and child.poll() is None:
            time.sleep(0.2)
        time.sleep(1.0)
        os.killpg(child.pid, signum)  # dive and its virtual agent alike
        out, err = child.communicate(timeout=60)
    finally:
        if child.poll() is None:
            os.killpg(child.pid, signal.SIGKILL)
            child.wait()
    [recording] = list(tmp_path.glob("*.mcap"))
    assert child.returncode == 130, err
    assert str(recording) in out and "another agent" not in err
    summary = summarize(recording)
    assert summary.link_losses == 0 and summary.sessions == 1  # the agent lived until the run stopped it
