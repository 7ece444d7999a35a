"""How a check ends other than passing. Below the probe and the registry, which both raise them."""

from __future__ import annotations


class CheckFailed(AssertionError):
    """A check saw the agent break the sentence it tests; the message says what was seen."""


class CheckSkipped(Exception):
    """A check cannot run against this agent (no key, not enough logged samples...); the message says why."""
