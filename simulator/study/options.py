"""What one `dive study` invocation runs: (plant preset, learner, region) combinations and their configs."""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum
from typing import Any

from learning import LearnerConfig, learner_preset
from simulator.errors import SimulatorError
from simulator.parameters import PlantParams, is_hardware, preset

SIMULATION_REGION = (0.1, 0.04)  # paper V-A: |z - z_d| < 0.1 m, |z'| < 0.04 m/s
EXPERIMENT_REGION = (0.15, 0.03)  # paper V-B, the experiment on the real agent


class Exploration(StrEnum):
    """How the learner explores, whatever its preset says (PRESET: as the preset says)."""

    PRESET = "preset"
    PAPER = "paper"  # 10 % falling linearly to 0 at episode 1000 (paper V-A)
    NONE = "none"  # only the optimism of untried pairs
    BONUS = "bonus"  # MBIE-EB: beta / sqrt(n) added to each pair's reward


class Ties(StrEnum):
    """When a state whose two actions have equal Q gets its action drawn."""

    PRESET = "preset"
    PER_PLAN = "per-plan"  # once per planning call: the tied state repeats one action for an episode
    PER_STEP = "per-step"  # afresh at every step


@dataclass(frozen=True)
class LearnerOptions:
    """Command-line overrides of the learner presets; None keeps the preset's value."""

    exploration: Exploration = Exploration.PRESET
    bonus: float = 0.5
    ties: Ties = Ties.PRESET
    actuator_bins: int | None = None
    velocity_diff_steps: int | None = None
    dirichlet_weight: float | None = None
    max_sweeps: int | None = None
    z_tol_m: float | None = None
    zdot_tol_mps: float | None = None

    def overrides(self) -> dict[str, Any]:
        """LearnerConfig fields these options replace."""
        out: dict[str, Any] = {}
        if self.exploration is Exploration.PAPER:
            out.update(p_explore_start=0.10, p_explore_end=0.0, explore_decay_episodes=1000, count_bonus=0.0)
        elif self.exploration is Exploration.NONE:
            out.update(p_explore_start=0.0, p_explore_end=0.0, count_bonus=0.0)
        elif self.exploration is Exploration.BONUS:
            out.update(p_explore_start=0.0, p_explore_end=0.0, count_bonus=self.bonus)
        if self.ties is not Ties.PRESET:
            out["ties_per_step"] = self.ties is Ties.PER_STEP
        for name in ("actuator_bins", "velocity_diff_steps", "dirichlet_weight", "max_sweeps", "z_tol_m",
                     "zdot_tol_mps"):
            value = getattr(self, name)
            if value is not None:
                out[name] = value
        return out


@dataclass(frozen=True)
class RunSpec:
    """One study of a run: plant preset, learner preset name, their configs, and a label for tables."""

    preset: str
    learner: str
    params: PlantParams
    config: LearnerConfig
    label: str

    @property
    def slug(self) -> str:
        """The label as a folder name."""
        return self.label.replace("/", "_").replace("@", "_").replace(" ", "")


def _region_label(config: LearnerConfig) -> str:
    return f"{config.z_tol_m:g}/{config.zdot_tol_mps:g}"


def expand_runs(
    items: list[str], default_preset: str, options: LearnerOptions, params_override: Any = None
) -> list[RunSpec]:
    """Runs of `items` ("learner" or "preset/learner"); the hardware preset without a region given runs
    in both the simulation's region and the experiment's."""
    if not items:
        raise SimulatorError("no learner given")
    runs: list[RunSpec] = []
    overrides = options.overrides()
    region_given = options.z_tol_m is not None or options.zdot_tol_mps is not None
    for item in items:
        preset_name, _, learner = item.strip().rpartition("/")
        preset_name = preset_name or default_preset
        params = preset(preset_name)
        if params_override is not None:
            params = params_override(params)
        config = learner_preset(learner, **overrides)
        regions = [None] if (region_given or not is_hardware(preset_name)) else [SIMULATION_REGION,
                                                                                 EXPERIMENT_REGION]
        for region in regions:
            c = config if region is None else replace(config, z_tol_m=region[0], zdot_tol_mps=region[1])
            label = f"{preset_name}/{learner}"
            if region is not None or region_given:
                label += f"@{_region_label(c)}"
            runs.append(RunSpec(preset_name, learner, params, c, label))
    return runs
