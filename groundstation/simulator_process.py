"""Runs the simulator as a separate process: the ground station never imports it (see style.md)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Sequence

PROG_NAME_VARIABLE = "DIVE_SIMULATOR_PROG_NAME"  # read by simulator/cli.py (the two packages share no import)


def simulator_command(args: Sequence[str]) -> list[str]:
    """The argv that runs `python -m simulator ARGS` with this interpreter."""
    return [sys.executable, "-m", "simulator", *args]


def run_simulator_command(args: Sequence[str]) -> int:
    """Run the simulator CLI in the foreground, passing the terminal through; returns its exit code.

    Its help and usage lines then say `dive ...`, the command the user typed (simulator/cli.py). A SIGTERM
    to `dive` is passed on, so the agent shuts down cleanly (closing its port) instead of being orphaned.
    """
    child = subprocess.Popen(simulator_command(args), env={**os.environ, PROG_NAME_VARIABLE: "dive"})

    def pass_on(signum: int, _frame: object) -> None:
        child.send_signal(signum)

    previous = signal.signal(signal.SIGTERM, pass_on)
    try:
        while True:
            try:
                return child.wait()
            except KeyboardInterrupt:
                # From a terminal the child got the Ctrl-C too and is shutting down; sent to dive alone
                # (kill -INT), it is passed on.
                try:
                    return child.wait(timeout=2.0)
                except subprocess.TimeoutExpired:
                    child.send_signal(signal.SIGINT)
    finally:
        signal.signal(signal.SIGTERM, previous)
