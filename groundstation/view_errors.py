"""Errors of the view and the replay (the CLI maps each to one line and a non-zero exit)."""

from __future__ import annotations


class ViewError(RuntimeError):
    """The viewer could not be started, or a recording could not be shown."""


class ReplayError(ViewError, OSError):
    """A recording that cannot be read: missing, not an MCAP file, or nothing decodable in it."""
