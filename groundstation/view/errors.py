"""Errors of the live view and the replay (the CLI maps each to one line and a non-zero exit)."""

from __future__ import annotations

from groundstation.errors import GroundStationError


class ViewError(GroundStationError, RuntimeError):
    """The viewer could not be started, or a recording could not be shown."""


class ReplayError(ViewError, ValueError):
    """A replay request that cannot be met: a bad range or speed, or nothing to show in the file."""


class PrivateViewerUnavailable(ViewError):
    """The web viewer cannot be kept to the run's owner on this machine (no private network): it is not served."""
