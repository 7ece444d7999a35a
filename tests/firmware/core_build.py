"""Compiling the firmware core for host tests, and starting the C agent: cc on the sources, skipped with one line when
cc is missing."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
FIRMWARE = ROOT / "firmware"
INCLUDES = [f"-I{FIRMWARE / d}" for d in ("include", "src", "generated")]
CFLAGS = ["-std=c99", "-Wall", "-Wextra", "-Werror", "-O1"]


def require_cc() -> str:
    """The C compiler, or skip the test."""
    cc = shutil.which("cc") or shutil.which("gcc")
    if cc is None:
        pytest.skip("no C compiler (cc) on PATH: firmware host tests skipped")
    return cc


def compile_program(sources: list[Path], out: Path) -> Path:
    """An executable of the given sources (paths relative to the repository or absolute)."""
    cc = require_cc()
    command = [cc, *CFLAGS, *INCLUDES, *[str(ROOT / s) for s in sources], "-o", str(out)]
    result = subprocess.run(command, capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr
    return out


def use_firmware_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """One build cache for the host library per test session (every agent after the first loads that build).

    Sets DIVE_FIRMWARE_CACHE for this process and the agents it starts; skips without a C compiler.
    """
    require_cc()
    cache = tmp_path_factory.getbasetemp() / "firmware-cache"
    cache.mkdir(exist_ok=True)
    os.environ["DIVE_FIRMWARE_CACHE"] = str(cache)
    return cache


@contextmanager
def c_agent(*transport: str, seed: int) -> Iterator[str]:
    """`python -m simulator serve --firmware c` at max speed on `transport` while inside: yields the address or
    device it prints first; fails the test with its stderr if it prints none. Terminated on the way out."""
    child = subprocess.Popen([sys.executable, "-m", "simulator", "serve", *transport, "--speed", "max", "--seed",
                              str(seed), "--firmware", "c"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert child.stdout is not None
    try:
        first = child.stdout.readline().strip()
        if not first:
            child.wait(10)
            pytest.fail(f"the C agent did not start: {child.stderr.read() if child.stderr else ''}")
        yield first
    finally:
        child.terminate()
        child.wait(10)


def session_folder(tmp_path_factory: pytest.TempPathFactory, name: str) -> Path:
    """A folder of this test session that its xdist workers share (each worker has a temp folder of its own inside
    the session's), for a build made once per session under a lock."""
    base = tmp_path_factory.getbasetemp()
    folder = (base.parent if os.environ.get("PYTEST_XDIST_WORKER") else base) / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder
