"""Checks made before anything starts, so bad input is one line at once, not an error from a child 10 s later."""

from __future__ import annotations

import errno

from groundstation.errors import GroundStationError


class UsageError(GroundStationError, ValueError):
    """A value the user gave that cannot work (the CLI exits 2, like a usage error)."""


def port_problem(port: int, option: str) -> str:
    """Why `port` cannot be served on ("" when it can): another process listens there (its viewer would show that
    process's data), or it needs privileges."""
    import socket  # here: `dive --help` does not need it
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        try:
            probe.bind(("0.0.0.0", port))
        except OSError as e:
            if e.errno in (errno.EADDRINUSE, errno.EACCES):
                why = "is in use by another process" if e.errno == errno.EADDRINUSE else "needs privileges"
                return f"port {port} {why}: choose another with {option}"
            raise
    return ""


def check_port_free(port: int, option: str) -> None:
    """Fail at once when `port` cannot be served on."""
    problem = port_problem(port, option)
    if problem:
        raise UsageError(problem)


def free_port() -> int:
    """A port nobody listens on now (the system's choice)."""
    import socket
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("0.0.0.0", 0))
        return int(probe.getsockname()[1])


def parse_speed(text: str) -> float | None:
    """`max` (None) or a positive factor; `10x` and `10` both mean ten times real time."""
    if text.strip().lower() == "max":
        return None
    try:
        speed = float(text.strip().lower().removesuffix("x"))
    except ValueError:
        speed = 0.0
    if not speed > 0 or speed == float("inf"):
        raise UsageError(f"bad speed {text!r}: give a factor such as 1, 10 or max")
    return speed


# The simulator's plant presets (simulator.parameters.preset_names(); a test keeps the two equal): groundstation
# starts the simulator as a process and never imports it, and a wrong name must be refused before that start.
PLANT_PRESETS = ("hardware", "hardware-fast", "paper")


def check_presets(preset: str | None, learner: str | None) -> None:
    """A plant or learner preset the virtual agent does not know is one line (exit 2) before it is started."""
    if preset is not None and preset not in PLANT_PRESETS:
        raise UsageError(f"unknown --preset {preset!r}; choose one of {', '.join(PLANT_PRESETS)}")
    if learner is not None:
        from learning.presets import learner_names

        if learner not in learner_names():
            raise UsageError(f"unknown --learner {learner!r}; choose one of {', '.join(learner_names())}")
