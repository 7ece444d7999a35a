"""The virtual agent's parameter table: protocol.parameters' definitions bound to its configuration objects."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from enum import Enum
from typing import Any, TypeVar

from learning import VELOCITY_FILTER, LearnerConfig, learner_memory_bytes, n_states
from protocol import messages
from protocol.parameters import PARAMS, RAM_BUDGET_BYTES, ParamDef, snapshot_ram_bytes
from simulator.errors import ParamsError

T = TypeVar("T")


class Scope(Enum):
    """Which configuration object a parameter belongs to."""

    LEARNER = "learner"  # LearnerConfig
    PLANT = "plant"  # PlantParams figures the on-board program applies itself (target, action step, ...)
    MISSION = "mission"  # MissionConfig


@dataclass(frozen=True)
class Binding:
    """Where the virtual agent keeps one parameter: a field of one configuration object."""

    scope: Scope
    field: str
    inverted: bool = False  # a bool field holding the parameter's negation
    # A BOOL switching a group of fields: 1 sets them to these values, 0 to 0 (False); it reads 1 while `field` is > 0.
    switch: dict[str, Any] | None = None


L, P, M = Scope.LEARNER, Scope.PLANT, Scope.MISSION
BINDINGS: dict[str, Binding] = {
    "target_depth_m": Binding(P, "target_depth_m"),
    "z_tol_m": Binding(L, "z_tol_m"),
    "zdot_tol_mps": Binding(L, "zdot_tol_mps"),
    "z_cells": Binding(L, "z_cells"),
    "zdot_cells": Binding(L, "zdot_cells"),
    "act_bins": Binding(L, "actuator_bins"),
    "gamma": Binding(L, "gamma"),
    "vi_tol": Binding(L, "vi_tolerance"),
    "term_reward": Binding(L, "terminal_reward"),
    "p_explore_start": Binding(L, "p_explore_start"),
    "p_explore_end": Binding(L, "p_explore_end"),
    "explore_eps": Binding(L, "explore_decay_episodes"),
    "known_count": Binding(L, "known_count"),
    "depth_only_term": Binding(L, "depth_only_terminal"),
    "random_ties": Binding(L, "random_ties"),
    "success_time_s": Binding(P, "episode_limit_s"),
    "control_dt_s": Binding(P, "control_period_s"),
    "action_step_deg": Binding(P, "action_step_deg"),
    "action_win_deg": Binding(P, "action_window_deg"),
    "link_timeout_s": Binding(M, "link_timeout_s"),
    "surface_on_link_loss": Binding(M, "surface_on_link_loss"),
    "dump_each_episode": Binding(M, "dump_each_episode"),
    "max_dive_s": Binding(M, "max_dive_s"),
    "max_episodes": Binding(M, "max_episodes"),
    "low_batt_v": Binding(M, "low_battery_v"),
    "start_at_rest": Binding(P, "start_with_recovery", inverted=True),
    "shared_model": Binding(L, "shared_model"),
    "dirichlet_w": Binding(L, "dirichlet_weight"),
    "count_bonus": Binding(L, "count_bonus"),
    "vel_diff_steps": Binding(L, "velocity_diff_steps"),
    "ties_per_step": Binding(L, "ties_per_step"),
    "max_sweeps": Binding(L, "max_sweeps"),
    "in_place_sweeps": Binding(L, "in_place_sweeps"),
    "vel_penalty": Binding(L, "velocity_penalty"),
    "velocity_filter": Binding(L, "filter_depth_gain", switch=VELOCITY_FILTER),
    "plan_stable_sweeps": Binding(L, "plan_stable_sweeps"),
    "plan_loose_tol": Binding(L, "plan_loose_tolerance"),
    "fine_step_deg": Binding(L, "fine_step_deg"),
    "fine_speed_mps": Binding(L, "fine_speed_mps"),
    "fine_reversal_deg": Binding(L, "fine_reversal_deg"),
    "plan_growth": Binding(L, "plan_growth"),
}


def binding(definition: ParamDef) -> Binding:
    return BINDINGS[definition.name]


def check_value(definition: ParamDef, value: float) -> float:
    """The value as the agent stores it, or ParamsError with the BAD_VALUE reason (SPEC.md section 13)."""
    why = definition.refusal(value)
    if why:
        raise ParamsError(why)
    return definition.stored(value)


class ParamTable:
    """Current values of the parameters, read from and written back to the configuration objects."""

    def __init__(self, sources: dict[Scope, Any], defs: tuple[ParamDef, ...] = PARAMS) -> None:
        self.defs = defs
        self._by_name = {d.name: i for i, d in enumerate(defs)}
        self.values: list[float] = []
        for d in defs:
            b = binding(d)
            raw = float(getattr(sources[b.scope], b.field))
            if b.switch is not None:
                raw = float(raw > 0.0)
            # Stored as the agent stores it: a preset's 0.4 is held (and sent) as the f32 0.4000000059604645.
            self.values.append(d.stored(1.0 - raw if b.inverted else raw))
        self._messages: dict[int, messages.ParamValue] = {}  # the last PARAM_VALUE built for each index

    def __len__(self) -> int:
        return len(self.defs)

    def lookup(self, index: int, name: str = "") -> int:
        """The index of a parameter given by index, or by name when index is -1; ParamsError if none."""
        if index == -1:
            try:
                return self._by_name[name]
            except KeyError:
                raise ParamsError(f"no parameter named {name!r}") from None
        if not 0 <= index < len(self.defs):
            raise ParamsError(f"no parameter with index {index}")
        return index

    def value(self, name: str) -> float:
        return self.values[self._by_name[name]]

    def set(self, index: int, value: float) -> float:
        """Store a value (after check_value); returns the value applied."""
        stored = check_value(self.defs[index], value)
        self.values[index] = stored
        return stored

    def apply(self, scope: Scope, base: T) -> T:
        """base (a frozen dataclass of that scope) with the table's current values."""
        kinds = {f.name: f.type for f in fields(base)}  # type: ignore[arg-type]
        changes: dict[str, Any] = {}
        for definition, value in zip(self.defs, self.values, strict=True):
            b = binding(definition)
            if b.scope is scope and b.switch is not None:
                # On in the base already (a learner preset's own gains): kept; else switched to the group's values.
                if not (value and getattr(base, b.field) > 0.0):
                    changes.update({name: gain if value else type(gain)(0) for name, gain in b.switch.items()})
            elif b.scope is scope:
                kind = str(kinds[b.field])
                if b.inverted:
                    value = 1.0 - value
                changes[b.field] = bool(value) if kind == "bool" else int(value) if kind == "int" else value
        return replace(base, **changes)  # type: ignore[type-var]

    def message(self, index: int) -> messages.ParamValue:
        """The PARAM_VALUE of one parameter (every PARAM_GET answers with one: kept while its value is unchanged)."""
        value = self.values[index]
        kept = self._messages.get(index)
        # The very float object stored, not an equal one: -0.0 == 0.0 but does not pack to the same bytes.
        if kept is not None and kept.value is value:
            return kept
        d = self.defs[index]
        built = messages.ParamValue(
            index=index, count=len(self.defs), param_type=int(d.param_type), value=value,
            minimum=d.minimum, maximum=d.maximum, name=d.name,
        )
        self._messages[index] = built
        return built


def check_ram(config: LearnerConfig) -> None:
    """ParamsError naming the bytes if the learner and its snapshots would not fit the RAM budget (SPEC s. 13)."""
    states = n_states(config)
    need = learner_memory_bytes(config) + snapshot_ram_bytes(states, config.shared_model)
    if need > RAM_BUDGET_BYTES:
        raise ParamsError(
            f"{states} states need {need} bytes of RAM (learner and snapshots), the budget is {RAM_BUDGET_BYTES}"
        )
