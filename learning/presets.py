"""Named learners for the study: the paper's, and the upgrades measured in diving-agent.md section 7."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

from learning.config import LearnerConfig
from learning.errors import LearnerConfigError

_SHARED = LearnerConfig(shared_model=True, p_explore_start=0.0, in_place_sweeps=True)

_PRESETS: dict[str, LearnerConfig] = {
    # Section III as printed, errata fixed.
    "paper": LearnerConfig(),
    # The paper's own future work: the actuator position (3 bins around neutral) joins the state.
    "actuator3": LearnerConfig(actuator_bins=3),
    # R-MAX: a pair counts as known after m = 3 tries; until then it is valued optimistically.
    "rmax": LearnerConfig(known_count=3),
    # Every printed reading at once, for the errata demonstration.
    "literal": LearnerConfig(explore_literal_gt=True, policy_argmin=True, alg4_printed=True),
    # The shared (relocatable) model of learning/shared.py, no exploration beyond the optimism of untried
    # types, in-place sweeps. Named ingredient by ingredient.
    "shared": _SHARED,
    "shared-bins3": replace(_SHARED, actuator_bins=3),
    "shared-bins13": replace(_SHARED, actuator_bins=13),
    # The velocity the learner sees: its own 4-step depth difference instead of the observer's estimate.
    "shared-bins13-diff4": replace(_SHARED, actuator_bins=13, velocity_diff_steps=4),
    # For the hardware preset (issue 17's per-trial goals): 7 actuator bins, an 8-step depth difference,
    # a terminal reward of -100 instead of -10 and a reward that also loses 1 s x |velocity|. Each is a
    # remedy for what ended late episodes: a rush from the region's depth edge that met its velocity edge
    # (docs/reproduction.md, "Why single trials kept failing").
    "shared-bins7-diff8-term100-vpen1": replace(
        _SHARED, actuator_bins=7, velocity_diff_steps=8, terminal_reward=-100.0, velocity_penalty=1.0
    ),
    # The same with 20 depth cells of 1 cm (region 0.1): the shared model learns them for free (it pools over
    # depth); a finer cell tells the agent better when to brake.
    "shared-z20-bins7-diff8-term100-vpen1": replace(
        _SHARED, z_cells=20, actuator_bins=7, velocity_diff_steps=8, terminal_reward=-100.0, velocity_penalty=1.0
    ),
    # Per-state counts as well, the shared histogram their Dirichlet prior worth 10 transitions: keeps
    # working where dynamics depend on depth.
    "shared-dirichlet": replace(_SHARED, dirichlet_weight=10.0),
    # The paper's exploration schedule on the shared model (it hurts), and an MBIE-EB count bonus.
    "shared-epsilon": replace(_SHARED, p_explore_start=0.10),
    "shared-bonus": replace(_SHARED, count_bonus=0.5),
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
