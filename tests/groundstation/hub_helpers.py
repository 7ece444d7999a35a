"""`dive` as a user types it, in tests: the CLI as a child process with its runtime folder in the test's tmp_path."""

from __future__ import annotations

import os
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


@contextmanager
def running(runtime: Path, url: str, out: Path) -> Iterator[subprocess.Popen[str]]:
    """`dive run URL` until the block ends with a Ctrl-C (SIGINT)."""
    before = set((runtime / "runs").glob("*.json")) if (runtime / "runs").is_dir() else set()
    proc = subprocess.Popen([*DIVE, "run", url, "--out", str(out)], env=dive_env(runtime), stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and proc.poll() is None:
            if set((runtime / "runs").glob("*.json")) - before:
                break
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
