"""The one exception base of the learning package and its configuration error."""

from __future__ import annotations


class LearningError(Exception):
    """Base of every error the learning package raises."""


class LearnerConfigError(LearningError, ValueError):
    """A learner configuration that cannot work (bad grid, bad probabilities, unknown preset)."""
