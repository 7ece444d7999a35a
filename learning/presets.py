"""Named learners for the study: the paper's, and the upgrades measured in diving-agent.md section 7."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from learning.config import LearnerConfig
from learning.errors import LearnerConfigError

_PRESETS: dict[str, LearnerConfig] = {
    # Section III as printed, errata fixed.
    "paper": LearnerConfig(),
    # The paper's own future work: the actuator position (3 bins around neutral) joins the state.
    "actuator3": LearnerConfig(actuator_bins=3),
    # R-MAX: a pair counts as known after m = 3 tries; until then it is valued optimistically.
    "rmax": LearnerConfig(known_count=3),
    # Every printed reading at once, for the errata demonstration.
    "literal": LearnerConfig(explore_literal_gt=True, policy_argmin=True, alg4_printed=True),
}


def learner_names() -> list[str]:
    """Names accepted by learner_preset."""
    return sorted(_PRESETS)


def learner_preset(name: str, **overrides: Any) -> LearnerConfig:
    """The named learner configuration, optionally with fields replaced."""
    try:
        config = _PRESETS[name]
    except KeyError:
        choices = ", ".join(learner_names())
        raise LearnerConfigError(f"unknown learner {name!r}; choose one of {choices}") from None
    return replace(config, **overrides) if overrides else config
