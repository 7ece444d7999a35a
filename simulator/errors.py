"""The one exception base of the simulator package and its specific errors, and how a command says one."""

from __future__ import annotations

import sys

import click


class SimulatorError(Exception):
    """Base of every error the simulator package raises."""


class ParamsError(SimulatorError, ValueError):
    """An unknown preset, an unreadable or invalid parameter file, a value out of range."""


class StudyError(SimulatorError):
    """A study that cannot run: bad trial counts, an unwritable output folder."""


class ClusterUnreachableError(SimulatorError, ConnectionError):
    """The Dask scheduler named by --cluster does not answer (a failure, exit 1, not bad usage)."""


def say_error(message: str) -> None:
    """One line on stderr, named after the program as it was called: `dive: ...` under `dive sim` / `dive study`
    (as every dive command says it), `python -m simulator: ...` when started on its own."""
    context = click.get_current_context(silent=True)
    program = context.find_root().info_name if context is not None else None
    print(f"{program or 'simulator'}: {message}", file=sys.stderr)
