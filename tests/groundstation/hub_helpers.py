"""`dive` as a user types it, in tests: the CLI as a child process with its runtime folder in the test's tmp_path."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

DIVE = [sys.executable, "-m", "groundstation.cli.app"]


def dive_env(runtime: Path) -> dict[str, str]:
    """The environment of a `dive` child: its runtime folder given, no link or key from the developer's shell."""
    inherited = {k: v for k, v in os.environ.items() if k not in ("DIVE_URL", "DIVE_KEY_FILE")}
    return {**inherited, "DIVE_RUNTIME_DIR": str(runtime), "COLUMNS": "200"}


def dive(runtime: Path, *args: str, timeout: float = 30.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*DIVE, *args], env=dive_env(runtime), capture_output=True, text=True, timeout=timeout)


def one_line_failure(done: subprocess.CompletedProcess[str], text: str, code: int = 1) -> None:
    """The command failed with `code` and said why in one line holding `text`, no traceback."""
    assert done.returncode == code, (done.stdout, done.stderr)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and text in lines[0] and "Traceback" not in done.stderr, done.stderr


def hub_announced(runtime: Path) -> set[Path]:
    """The runs announced in `runtime` whose hub is up (a run is announced while it connects, before its hub)."""
    up = set()
    for path in (runtime / "runs").glob("*.json"):
        try:
            if json.loads(path.read_text()).get("state", "running") == "running":
                up.add(path)
        except (OSError, ValueError):
            continue  # being replaced, or gone
    return up


@contextmanager
def running(runtime: Path, url: str, out: Path, *options: str,
            start_timeout_s: float = 30.0) -> Iterator[subprocess.Popen[str]]:
    """`dive run URL OPTIONS` until the block ends with a Ctrl-C (SIGINT); its hub announced before the block."""
    before = hub_announced(runtime)
    proc = subprocess.Popen([*DIVE, "run", url, "--out", str(out), *options], env=dive_env(runtime),
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + start_timeout_s
        while time.monotonic() < deadline and proc.poll() is None:
            if hub_announced(runtime) - before:
                break
            time.sleep(0.05)
        assert proc.poll() is None, proc.communicate()
        yield proc
    finally:
        interrupt(proc)


def interrupt(proc: subprocess.Popen[str]) -> None:
    """Ctrl-C (SIGINT) to a `dive` child still running, as a user ends it; killed if it has not ended in 30 s."""
    if proc.poll() is None:
        proc.send_signal(signal.SIGINT)
    try:
        proc.wait(30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


# The virtual agent the control tests drive: fast enough for episodes in seconds, slow enough to command.
SIM = "sim://?speed=20&seed=4"


def agent_mode(runtime: Path) -> str:
    """The agent's mode as `dive status` reports it through the run's hub."""
    done = dive(runtime, "status")
    assert done.returncode == 0, done.stderr
    found = re.search(r"^mode (\w+),", done.stdout, re.MULTILINE)
    assert found is not None, done.stdout
    return found.group(1)


def until_mode(runtime: Path, wanted: set[str], timeout_s: float = 60.0) -> str:
    """Polls `dive status` until the agent is in one of `wanted` (or the time is up): the mode it was last in."""
    deadline = time.monotonic() + timeout_s
    while True:
        mode = agent_mode(runtime)
        if mode in wanted or time.monotonic() > deadline:
            return mode
        time.sleep(0.5)
