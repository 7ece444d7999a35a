"""The one exception base of the simulator package and its specific errors."""

from __future__ import annotations


class SimulatorError(Exception):
    """Base of every error the simulator package raises."""


class ParamsError(SimulatorError, ValueError):
    """An unknown preset, an unreadable or invalid parameter file, a value out of range."""


class StudyError(SimulatorError):
    """A study that cannot run: bad trial counts, an unwritable output folder."""
