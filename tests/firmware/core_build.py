"""Compiling the firmware core for host tests: cc on the sources, skipped with one line when cc is missing."""

from __future__ import annotations

import shutil
import subprocess
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
