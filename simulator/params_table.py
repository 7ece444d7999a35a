"""The agent's parameter table: every learner and mission parameter by index and name, typed and range-checked."""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, fields, replace
from enum import Enum
from typing import Any, TypeVar

from protocol import ParamType, messages
from simulator.errors import ParamsError

MAX_NAME_BYTES = 16  # PARAM_VALUE.name is char[16]
_F32 = struct.Struct("<f")

T = TypeVar("T")


class Scope(Enum):
    """Which configuration object a parameter belongs to, and so when it may change."""

    LEARNER = "learner"  # LearnerConfig: changes the learner, so not while learning or recovering
    PLANT = "plant"  # PlantParams figures the on-board program applies itself (target, action step, ...)
    MISSION = "mission"  # MissionConfig: any time


@dataclass(frozen=True)
class ParamDef:
    name: str  # wire name, unit as suffix, at most 16 bytes
    scope: Scope
    field: str  # field of the scope's dataclass
    param_type: ParamType
    minimum: float
    maximum: float
    doc: str


def _d(name: str, scope: Scope, field: str, kind: ParamType, low: float, high: float, doc: str) -> ParamDef:
    return ParamDef(name, scope, field, kind, low, high, doc)


L, P, M = Scope.LEARNER, Scope.PLANT, Scope.MISSION
B, U8, I32, U32, F = ParamType.BOOL, ParamType.U8, ParamType.I32, ParamType.U32, ParamType.F32

# Index order is the wire order: append only, so a ground station's cached table stays valid.
PARAM_DEFS: tuple[ParamDef, ...] = (
    _d("target_depth_m", P, "target_depth_m", F, 0.05, 2.5, "target depth z_d (sensor reads to ~2.9 m)"),
    _d("z_tol_m", L, "z_tol_m", F, 0.01, 1.0, "half-height of the learning region"),
    _d("zdot_tol_mps", L, "zdot_tol_mps", F, 0.001, 0.5, "velocity bound of the learning region"),
    _d("z_cells", L, "z_cells", U8, 1, 50, "depth cells of the grid"),
    _d("zdot_cells", L, "zdot_cells", U8, 1, 50, "velocity cells of the grid"),
    _d("act_bins", L, "actuator_bins", U8, 1, 9, "actuator position bins in the state (1 = paper)"),
    _d("gamma", L, "gamma", F, 0.0, 0.999, "discount factor"),
    _d("vi_tol", L, "vi_tolerance", F, 1e-7, 0.1, "value iteration stops below this change"),
    _d("term_reward", L, "terminal_reward", F, -1000.0, 0.0, "reward on entering the terminal state"),
    _d("p_explore_start", L, "p_explore_start", F, 0.0, 1.0, "exploration probability at episode 0"),
    _d("p_explore_end", L, "p_explore_end", F, 0.0, 1.0, "exploration probability after the decay"),
    _d("explore_eps", L, "explore_decay_episodes", U32, 1, 1_000_000, "episodes of the exploration decay"),
    _d("known_count", L, "known_count", U8, 1, 255, "tries before a pair is known (1 = paper, >1 R-MAX)"),
    _d("depth_only_term", L, "depth_only_terminal", B, 0, 1, "episode ends on depth only (authors' code)"),
    _d("random_ties", L, "random_ties", B, 0, 1, "break ties between equal Q values at random"),
    _d("success_time_s", P, "episode_limit_s", F, 1.0, 3600.0, "time in the region that counts as success"),
    _d("control_dt_s", P, "control_period_s", F, 0.02, 0.2, "learner period"),
    _d("action_step_deg", P, "action_step_deg", F, 0.1, 20.0, "gear angle change per learner action"),
    _d("action_win_deg", P, "action_window_deg", F, 0.5, 65.0, "learner's gear window around neutral, +/-"),
    _d("link_timeout_s", M, "link_timeout_s", F, 0.0, 3600.0, "link lost after this silence (0 = never)"),
    _d("surface_on_link", M, "surface_on_link_loss", B, 0, 1, "surface when the link is lost"),
    _d("dump_each_ep", M, "dump_each_episode", B, 0, 1, "send VALUES and POLICY after every episode"),
    _d("max_dive_s", M, "max_dive_s", F, 0.0, 86400.0, "surface after this long diving (0 = no limit)"),
    _d("max_episodes", M, "max_episodes", U32, 0, 1_000_000, "episodes per CMD_START giving 0 (0 = no limit)"),
    _d("low_batt_v", M, "low_battery_v", F, 3.0, 4.2, "surface below this battery voltage"),
)


def coerce(definition: ParamDef, value: float) -> float:
    """The value as the agent stores it (integers rounded toward zero, f32 rounded), or ParamsError."""
    if not math.isfinite(value):
        raise ParamsError(f"{definition.name}: {value} is not a finite number")
    if definition.param_type == ParamType.F32:
        stored = _F32.unpack(_F32.pack(value))[0] if abs(value) < 3.4e38 else value
    elif definition.param_type == ParamType.BOOL:
        stored = 1.0 if value != 0 else 0.0
    else:
        stored = float(math.trunc(value))
    # Range check on the stored value, with f32 rounding tolerated at the bounds.
    slack = 1e-6 * max(1.0, abs(definition.maximum), abs(definition.minimum))
    if definition.param_type != ParamType.F32:
        slack = 0.0
    if not definition.minimum - slack <= stored <= definition.maximum + slack:
        raise ParamsError(f"{definition.name}: {value} outside [{definition.minimum}, {definition.maximum}]")
    return stored


class ParamTable:
    """Current values of PARAM_DEFS, read from and written back to the configuration objects."""

    def __init__(self, sources: dict[Scope, Any], defs: tuple[ParamDef, ...] = PARAM_DEFS) -> None:
        self.defs = defs
        self._by_name = {d.name: i for i, d in enumerate(defs)}
        self.values: list[float] = [float(getattr(sources[d.scope], d.field)) for d in defs]

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
        """Store a value (after coerce); returns the value applied."""
        stored = coerce(self.defs[index], value)
        self.values[index] = stored
        return stored

    def apply(self, scope: Scope, base: T) -> T:
        """base (a frozen dataclass of that scope) with the table's current values."""
        kinds = {f.name: f.type for f in fields(base)}  # type: ignore[arg-type]
        changes: dict[str, Any] = {}
        for definition, value in zip(self.defs, self.values, strict=True):
            if definition.scope is scope:
                kind = str(kinds[definition.field])
                changes[definition.field] = bool(value) if kind == "bool" else int(value) if kind == "int" else value
        return replace(base, **changes)  # type: ignore[type-var]

    def message(self, index: int) -> messages.ParamValue:
        """The PARAM_VALUE of one parameter."""
        d = self.defs[index]
        return messages.ParamValue(
            index=index, count=len(self.defs), param_type=int(d.param_type), value=self.values[index],
            minimum=d.minimum, maximum=d.maximum, name=d.name,
        )
