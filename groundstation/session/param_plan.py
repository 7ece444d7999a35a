"""What a parameter set or load would do, before anything is sent: unchanged values, learner restarts, refusals.

From the one parameter definition (protocol/parameters.py): which parameters restart the learner (and which of
them change the state grid) and in which modes the agent refuses them.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from groundstation.errors import CommandError, ParameterError
from groundstation.session.control import known_mode, refused, wait_for_mode
from groundstation.session.params import Parameter, ParamTable, ParamType, parse_value
from protocol import Mode
from protocol.parameters import BY_NAME, ParamDef

if TYPE_CHECKING:
    from groundstation.session.agent_session import Session

GRID = ("target_depth_m", "z_tol_m", "zdot_tol_mps", "z_cells", "zdot_cells", "act_bins")  # the state grid


def as_stored(param: Parameter, value: float) -> float:
    """A value as the agent stores it (F32 parameters as f32), to compare a new value with the agent's."""
    if param.param_type == ParamType.F32:
        return float(struct.unpack("<f", struct.pack("<f", value))[0])
    return value


@dataclass
class ParamPlan:
    """The values of a set or load, sorted by what they would do on the agent."""

    changes: list[tuple[Parameter, float]] = field(default_factory=list)  # (the agent's parameter, the new value)
    unchanged: list[Parameter] = field(default_factory=list)

    @property
    def restarts(self) -> list[str]:
        """The changes that restart the learner (it forgets what it learned)."""
        return [p.name for p, _ in self.changes if (d := _definition(p.name)) is not None and d.learner]

    def refused_in(self, mode: int | None) -> list[str]:
        """The changes the agent refuses in `mode` (SPEC.md section 13's "refused in" column)."""
        if mode is None:
            return []
        return [p.name for p, _ in self.changes
                if (d := _definition(p.name)) is not None and mode in d.refused_in]

    def restart_warning(self) -> str:
        """What the restart costs, naming each parameter ("" when nothing restarts the learner)."""
        names = self.restarts
        if not names:
            return ""
        grid = [n for n in names if n in GRID]
        what = " and changes the state grid" if grid else ""
        return (f"changing {', '.join(names)} restarts the learner{what}: it forgets everything it learned")


def _definition(name: str) -> ParamDef | None:
    return BY_NAME.get(name)


def plan(table: ParamTable, values: dict[str, str]) -> ParamPlan:
    """Every name checked (did-you-mean) and every value parsed before anything is sent."""
    result = ParamPlan()
    for name, text in values.items():
        param = table.get(name)
        number = parse_value(param, text)
        if as_stored(param, number) == as_stored(param, param.value):
            result.unchanged.append(param)
        else:
            result.changes.append((param, number))
    return result


# SPEC s. 13: parameters are refused in LEARNING and RECOVERING only, never in PAUSED: pausing is enough (README)
_WHAT_TO_DO = {Mode.LEARNING: "pause first (dive pause), set them, then dive resume",
               Mode.RECOVERING: "pause first (dive pause), set them, then dive resume"}


def mode_refusal(names: list[str], mode: int) -> ParameterError:
    """One line naming each parameter the agent would refuse now, its mode and what to do."""
    known = Mode(mode) if mode in Mode._value2member_map_ else None
    what = _WHAT_TO_DO.get(known, "") if known is not None else ""
    mode_text = known.name if known is not None else f"mode {mode}"
    return ParameterError(f"not allowed while the agent is {mode_text}: {', '.join(names)}"
                          + (f"; {what}" if what else ""))


def checked_plan(s: Session, values: dict[str, str]) -> ParamPlan:
    """What a set or load would do, after every check that needs no confirmation: names, values and the agent's
    mode (a refusal names each parameter it would refuse). Nothing is sent."""
    change = plan(s.params, values)
    if change.changes and s.last_heartbeat is None:
        wait_for_mode(s, 1.5)  # the mode decides what the agent refuses
    mode = s.last_heartbeat.mode if s.last_heartbeat is not None else None
    refused_now = change.refused_in(mode)
    if refused_now and mode is not None:
        raise mode_refusal(refused_now, mode)
    return change


def apply(s: Session, change: ParamPlan, on_done: Callable[[Parameter], None] | None = None) -> list[Parameter]:
    """Send the changes (never the unchanged values); the values the agent applied, in order, each also given to
    `on_done` as it is applied (a refusal of a later one leaves the earlier ones said)."""
    done = []
    for p, value in change.changes:
        try:
            done.append(s.set_param(p.name, value))
        except CommandError as e:
            raise refused("PARAM_SET", e, known_mode(s), p.name) from None
        if on_done is not None:
            on_done(done[-1])
    return done


def describe(param: Parameter) -> str:
    """One line of `dive params`: value and unit, range, whether a change resets learning, what it is."""
    d = _definition(param.name)
    unit = d.unit if d is not None else ""
    resets = "resets learning" if d is not None and d.learner else ""
    doc = d.doc if d is not None else "(not in this ground station's table)"
    value = f"{param.display_value} {unit}".strip()
    return (f"{param.index:3d} {param.name:22s} {value:>14s}  [{param.minimum:g} .. {param.maximum:g}]"
            f"  {resets:15s}  {doc}")
