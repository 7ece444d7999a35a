"""The agent's parameters in Foxglove's Parameters panel: get and set through the session, with `dive params`' rules.

A set sends only what differs from the agent's values; one the agent would refuse in its mode is refused, naming
each parameter and the mode; one that restarts the learner (it forgets what it learned) goes ahead only when the
same values are set again within CONFIRM_S: the panel has no dialog, so the first set is answered with the old
values and a warning that says how to confirm, as `dive params set` asks on a terminal.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

import numpy as np
from foxglove import Parameter as FoxParameter
from foxglove import ParameterType

from groundstation.errors import GroundStationError
from groundstation.session.agent_session import Session
from groundstation.session.param_plan import ParamPlan, apply, checked_plan
from groundstation.session.params import Parameter
from protocol import ParamType

CONFIRM_S = 30.0  # a set that restarts the learner, repeated within this long, is confirmed
_WHOLE = (ParamType.U8, ParamType.I32, ParamType.U32)


def to_foxglove(param: Parameter) -> FoxParameter:
    """A parameter as the panel shows it: a toggle for BOOL, a whole number, or the shortest decimal that is the
    agent's f32 (0.95, not 0.949999988)."""
    if param.param_type == ParamType.BOOL:
        return FoxParameter(param.name, value=bool(param.value))
    if param.param_type in _WHOLE:
        return FoxParameter(param.name, value=int(param.value))
    shortest = float(np.format_float_positional(np.float32(param.value), unique=True, trim="0"))
    return FoxParameter(param.name, value=shortest, type=ParameterType.Float64)


def as_text(value: object) -> str:
    """A value from the panel as `dive params set` would take it from the command line."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


class ParameterBridge:
    """Get and set for the server's listener; `warn` shows a line in Foxglove (its problems list)."""

    def __init__(self, session: Callable[[], Session | None], warn: Callable[[str], None]) -> None:
        self._session = session
        self._warn = warn
        self._lock = threading.Lock()  # one set at a time: the confirmation compares with the set before
        self._unconfirmed: tuple[tuple[str, float], ...] = ()
        self._unconfirmed_s = 0.0

    def get(self, names: list[str]) -> list[FoxParameter]:
        """The agent's values, asked for now: the whole table (PARAM_LIST) when no name is given."""
        s = self._session()
        if s is None:
            return []
        try:
            if not names:
                return [to_foxglove(p) for p in s.refresh_params()]
            return [to_foxglove(s.get_param(name)) for name in names if name in s.params]
        except GroundStationError as e:
            self._warn(f"parameters: {e}")
            return [to_foxglove(s.params.get(name)) for name in names or [p.name for p in s.params]
                    if name in s.params]

    def set(self, parameters: list[FoxParameter]) -> list[FoxParameter]:
        """Set what differs, after `dive params set`'s checks; the agent's values of those parameters afterwards."""
        s = self._session()
        if s is None:
            self._warn("not attached to the agent yet: nothing set")
            return []
        values = {p.name: as_text(p.get_value()) for p in parameters}
        with self._lock:
            try:
                change = checked_plan(s, values)
                if self._confirmed(change):
                    apply(s, change)
            except GroundStationError as e:
                self._warn(str(e))
        return [to_foxglove(s.params.get(name)) for name in values if name in s.params]

    def _confirmed(self, change: ParamPlan) -> bool:
        """True when nothing restarts the learner, or when this restart is the one warned about within CONFIRM_S."""
        warning = change.restart_warning()
        if not warning:
            return True
        key = tuple(sorted((p.name, value) for p, value in change.changes))
        now = time.monotonic()
        if key == self._unconfirmed and now - self._unconfirmed_s <= CONFIRM_S:
            self._unconfirmed = ()
            return True
        self._unconfirmed, self._unconfirmed_s = key, now
        self._warn(f"{warning}: set the same value again within {CONFIRM_S:g} s to go ahead; nothing changed")
        return False
