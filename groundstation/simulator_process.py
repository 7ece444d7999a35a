"""Runs the simulator as a separate process: the ground station never imports it (see style.md)."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Sequence


def simulator_command(args: Sequence[str]) -> list[str]:
    """The argv that runs `python -m simulator ARGS` with this interpreter."""
    return [sys.executable, "-m", "simulator", *args]


def run_simulator_command(args: Sequence[str]) -> int:
    """Run the simulator CLI in the foreground, passing the terminal through; returns its exit code."""
    try:
        return subprocess.call(simulator_command(args))
    except KeyboardInterrupt:
        return 130
