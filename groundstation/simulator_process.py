"""Runs the simulator as a separate process: the ground station never imports it (see style.md)."""

from __future__ import annotations

import functools
import os
import signal
import subprocess
import sys
from collections.abc import Sequence
from typing import Any

PROG_NAME_VARIABLE = "DIVE_SIMULATOR_PROG_NAME"  # read by simulator/cli.py (the two packages share no import)


def simulator_command(args: Sequence[str]) -> list[str]:
    """The argv that runs `python -m simulator ARGS` with this interpreter. `-P`: the current folder is not put
    first on the import path, as `-m` otherwise does, so a `simulator/` folder in it (another user's, in /tmp or a
    shared folder the run is started from) is never what runs, as the run's user (issue 38)."""
    return [sys.executable, "-P", "-m", "simulator", *args]


def _die_with_parent(libc: Any) -> None:
    """In the child, before exec: SIGTERM when the parent dies, even by kill -9 (Linux prctl PR_SET_PDEATHSIG).

    So a killed `dive sim` or `dive run` never leaves a virtual agent running and holding its port. Elsewhere
    (no prctl) the parent's signal handlers are the only guard.
    """
    try:
        if libc is not None:
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGTERM)
    except AttributeError:
        pass
    if os.getppid() == 1:  # the parent died before prctl took effect
        os._exit(1)


PR_SET_PDEATHSIG = 1


def child_options() -> dict[str, Any]:
    """Popen options for a simulator child: it stops when this process dies (see _die_with_parent)."""
    if not sys.platform.startswith("linux"):
        return {}
    # ctypes is loaded here, in the parent: not at import (`dive --help` needs none of it), and not in the child,
    # which must not import between fork and exec (another thread may have held the import lock at the fork).
    import ctypes

    try:
        libc: Any = ctypes.CDLL(None, use_errno=True)
    except OSError:
        libc = None
    return {"preexec_fn": functools.partial(_die_with_parent, libc)}


def run_simulator_command(args: Sequence[str]) -> int:
    """Run the simulator CLI in the foreground, passing the terminal through; returns its exit code.

    Its help and usage lines then say `dive ...`, the command the user typed (simulator/cli.py). A SIGTERM
    or SIGHUP to `dive` is passed on, so the agent shuts down cleanly (closing its port) instead of being orphaned.
    """
    child = subprocess.Popen(simulator_command(args), env={**os.environ, PROG_NAME_VARIABLE: "dive"},
                             **child_options())

    def pass_on(signum: int, _frame: object) -> None:
        child.send_signal(signum)

    previous = {sig: signal.signal(sig, pass_on) for sig in (signal.SIGTERM, signal.SIGHUP)}
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
        for sig, handler in previous.items():
            signal.signal(sig, handler)
