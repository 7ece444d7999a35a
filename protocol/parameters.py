"""The agent's parameters, defined once: SPEC.md's table, the virtual agent and the C headers all come from here.

Index order is the wire order and only ever grows at the end, so a ground station's cached table stays valid.
Defaults are the real agent's (firmware) values; the virtual agent's presets override some of them at start.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

from protocol.enums import Mode, ParamType

NAME_BYTES = 24  # PARAM_VALUE.name, PARAM_GET.name, PARAM_SET.name are char[24]
_F32 = struct.Struct("<f")

# RAM the on-board learner may use on a Teensy 3.2 (64 KiB of RAM): SPEC.md section 13, "S and the RAM budget".
# 44 KiB leaves 20 KiB for the stack, the link buffers, the ACK memory and the rest of the firmware.
RAM_BUDGET_BYTES = 44 * 1024
SNAPSHOTS_HELD = 4  # snapshots an agent keeps (any kind); older ids are STALE
# The largest snapshot an agent copies is Q_VALUES, f32[S][2] = 8 S bytes (COUNTS is rendered from the live model).
SNAPSHOT_BYTES_PER_STATE = 8
# A shared-model learner keeps no Q table (Q comes from the values and the pooled histograms): its Q_VALUES
# snapshot is rendered live like COUNTS, so the largest copy is VALUES, f32[S] = 4 S bytes.
SHARED_SNAPSHOT_BYTES_PER_STATE = 4


def f32(value: float) -> float:
    """value rounded to the nearest f32, widened back exactly (what an agent storing f32 sends)."""
    if not math.isfinite(value) or abs(value) >= 3.4028235677973366e38:
        return value
    return float(_F32.unpack(_F32.pack(value))[0])


def snapshot_ram_bytes(states: int, shared_model: bool = False) -> int:
    """RAM for the held snapshot copies: SNAPSHOTS_HELD slots of the largest copied kind (SPEC.md section 13).

    Q_VALUES (8 S) for the per-state learners; VALUES (4 S) for a shared-model learner, whose Q_VALUES is
    rendered from the live model and values.
    """
    per_state = SHARED_SNAPSHOT_BYTES_PER_STATE if shared_model else SNAPSHOT_BYTES_PER_STATE
    return SNAPSHOTS_HELD * per_state * states


@dataclass(frozen=True)
class ParamDef:
    """One parameter as SPEC.md lists it and every agent reports it in PARAM_VALUE."""

    index: int
    name: str  # wire name, unit as suffix, at most NAME_BYTES bytes of UTF-8
    param_type: ParamType
    unit: str
    default: float  # the real agent's default
    minimum: float
    maximum: float
    refused_in: tuple[Mode, ...]  # modes in which PARAM_SET is refused with NOT_ALLOWED_IN_MODE
    learner: bool  # a change restarts the learner (as CMD_RESET_MODEL) and is checked against the RAM budget
    doc: str
    simulator_only: bool = False  # a real agent reports minimum = maximum = default
    optional: bool = False  # an agent may leave it out as minimum = maximum = default (SPEC.md 13, optional)

    @property
    def integral(self) -> bool:
        return self.param_type != ParamType.F32

    def firmware_range(self) -> tuple[float, float]:
        """(minimum, maximum) as a real agent reports them."""
        if self.simulator_only:
            return self.default, self.default
        return self.minimum, self.maximum

    def ranges_allowed(self) -> tuple[tuple[float, float], ...]:
        """The (minimum, maximum) pairs a conformant agent may report: the table's, and for an optional parameter
        it does not implement, (default, default) (SPEC.md 13, optional parameters)."""
        if self.optional or self.simulator_only:
            return (self.minimum, self.maximum), (self.default, self.default)
        return ((self.minimum, self.maximum),)

    def refusal(self, value: float, maximum: float | None = None) -> str:
        """Why PARAM_SET of `value` is refused with BAD_VALUE, or "" if it may be stored (SPEC.md section 13)."""
        high = self.maximum if maximum is None else maximum
        if not math.isfinite(value):
            return f"{self.name}: {value} is not a finite number"
        if self.integral and value != math.floor(value):
            return f"{self.name}: {value} is not an integer"
        stored = f32(value) if self.param_type == ParamType.F32 else value
        if not self.minimum <= stored <= high:
            return f"{self.name}: {value} outside [{self.minimum:g}, {high:g}]"
        return ""

    def stored(self, value: float) -> float:
        """The value as an agent stores it (f32 rounded for F32; integers unchanged); call refusal() first."""
        return f32(value) if self.param_type == ParamType.F32 else float(value)


_LEARNING = (Mode.LEARNING,)
_LEARNER = (Mode.LEARNING, Mode.RECOVERING)
_NEVER: tuple[Mode, ...] = ()
B, U8, U32, F = ParamType.BOOL, ParamType.U8, ParamType.U32, ParamType.F32


def _p(name: str, kind: ParamType, unit: str, default: float, low: float, high: float, refused: tuple[Mode, ...],
       doc: str, simulator_only: bool = False) -> tuple[str, ParamType, str, float, float, float, tuple[Mode, ...],
                                                        bool, str, bool]:
    return name, kind, unit, default, low, high, refused, refused == _LEARNER, doc, simulator_only


_ROWS = (
    _p("target_depth_m", F, "m", 0.4, 0.05, 2.5, _LEARNING, "target depth z_d (the sensor reads to about 2.9 m)"),
    _p("z_tol_m", F, "m", 0.1, 0.01, 1.0, _LEARNER, "half-height of the learning region"),
    _p("zdot_tol_mps", F, "m/s", 0.04, 0.001, 0.5, _LEARNER, "velocity bound of the learning region"),
    _p("z_cells", U8, "", 10, 1, 50, _LEARNER, "depth cells of the grid"),
    _p("zdot_cells", U8, "", 10, 1, 50, _LEARNER, "velocity cells of the grid"),
    _p("act_bins", U8, "", 1, 1, 13, _LEARNER, "actuator position bins in the state (1 = the paper)"),
    _p("gamma", F, "", 0.99, 0.0, 0.999, _LEARNER, "discount factor"),
    _p("vi_tol", F, "", 1e-4, 1e-7, 0.1, _LEARNER, "value iteration stops below this change"),
    _p("term_reward", F, "", -10.0, -1000.0, 0.0, _LEARNER, "reward on entering the terminal state"),
    _p("p_explore_start", F, "", 0.1, 0.0, 1.0, _LEARNER, "exploration probability at episode 0"),
    _p("p_explore_end", F, "", 0.0, 0.0, 1.0, _LEARNER, "exploration probability after the decay"),
    _p("explore_eps", U32, "episodes", 1000, 1, 1_000_000, _LEARNER, "episodes of the exploration decay"),
    _p("known_count", U8, "", 1, 1, 255, _LEARNER, "tries before a pair is known (1 = the paper, > 1 R-MAX)"),
    _p("depth_only_term", B, "", 0, 0, 1, _LEARNER, "an episode ends on depth only (the authors' code)"),
    _p("random_ties", B, "", 1, 0, 1, _LEARNER, "break ties between equal Q values at random"),
    _p("success_time_s", F, "s", 300.0, 1.0, 3600.0, _LEARNING, "time in the region that counts as success"),
    _p("control_dt_s", F, "s", 0.1, 0.02, 0.2, _LEARNING, "learner period (the control period)"),
    _p("action_step_deg", F, "deg", 2.1, 0.1, 20.0, _LEARNING, "gear angle change per learner action"),
    _p("action_win_deg", F, "deg", 19.5, 0.5, 65.0, _LEARNING, "gear window around the episode's centre (s. 10), +/-"),
    _p("link_timeout_s", F, "s", 10.0, 0.0, 3600.0, _NEVER, "link lost after this silence (0 = never)"),
    _p("surface_on_link_loss", B, "", 0, 0, 1, _NEVER, "surface when the link is lost"),
    _p("dump_each_episode", B, "", 0, 0, 1, _NEVER, "send VALUES then POLICY after every EPISODE_END"),
    _p("max_dive_s", F, "s", 0.0, 0.0, 86400.0, _NEVER, "surface after this long away from IDLE (0 = no limit)"),
    _p("max_episodes", U32, "episodes", 0, 0, 1_000_000, _NEVER,
       "episodes per CMD_START that gives 0 (0 = no limit)"),
    _p("low_batt_v", F, "V", 3.4, 3.0, 4.2, _NEVER, "surface below this battery voltage"),
    _p("start_at_rest", B, "", 0, 0, 1, _NEVER,
       "simulator only: 1 = an episode starts at once at a random state at rest, with no RECOVERING samples "
       "(the paper's simulation); a real agent reports minimum = maximum = 0", simulator_only=True),
    # The shared-model learners (learning/shared.py, issue 17).
    _p("shared_model", B, "", 0, 0, 1, _LEARNER,
       "shared model: one offset histogram per velocity cell, actuator bin and action, pooled over depth"),
    _p("dirichlet_w", F, "", 0.0, 0.0, 1000.0, _LEARNER,
       "shared model: per-state counts too, the shared histogram their prior of this weight (0 = off)"),
    _p("count_bonus", F, "", 0.0, 0.0, 100.0, _LEARNER, "MBIE-EB exploration bonus beta / sqrt(n) (0 = off)"),
    _p("vel_diff_steps", U8, "", 0, 0, 16, _LEARNER,
       "learner velocity from its own k-step depth difference (0 = the observer's)"),
    _p("ties_per_step", B, "", 0, 0, 1, _LEARNER, "draw a tied state's action at every step (0 = once per plan)"),
    _p("max_sweeps", U32, "", 100_000, 1, 1_000_000, _LEARNER, "value iteration sweeps per planning call at most"),
    _p("in_place_sweeps", B, "", 0, 0, 1, _LEARNER, "in-place (Gauss-Seidel) value iteration sweeps"),
    _p("vel_penalty", F, "s", 0.0, 0.0, 100.0, _LEARNER,
       "shared model: a cell's reward also loses this times its centre |velocity| (0 = the paper's -|z|)"),
    _p("velocity_filter", B, "", 0, 0, 1, _LEARNER,
       "learner velocity from a depth filter predicting with the commanded gear angle (0 = vel_diff_steps')"),
    # Planning's early stop (learning/config.py plan_stable_sweeps, plan_loose_tolerance; issue 29 item 6).
    _p("plan_stable_sweeps", U8, "", 0, 0, 100, _LEARNER,
       "shared model: a plan also ends once no greedy action has changed for this many sweeps and the last sweep "
       "moved no value by plan_loose_tol or more (0 = off)"),
    _p("plan_loose_tol", F, "", 0.0, 0.0, 10.0, _LEARNER,
       "the value change below which plan_stable_sweeps may end a plan"),
    # A smaller step near a hover (learning/config.py fine_step_deg, fine_speed_mps; issue 43).
    _p("fine_step_deg", F, "deg", 0.0, 0.0, 20.0, _LEARNER,
       "gear angle change per learner action while the learner's |velocity| is under fine_speed_mps (0 = off: "
       "action_step_deg always)"),
    _p("fine_speed_mps", F, "m/s", 0.0, 0.0, 0.5, _LEARNER,
       "the learner's |velocity| under which an action steps fine_step_deg"),
    # A larger step where the fine step applies and an action reverses the last one (learning/config.py
    # fine_reversal_deg; issue 43): it takes up a gear's lost motion.
    _p("fine_reversal_deg", F, "deg", 0.0, 0.0, 20.0, _LEARNER,
       "gear angle change per learner action where fine_step_deg applies and the action reverses the last one (or "
       "is the episode's first) (0 = off: fine_step_deg)"),
    # Planning on growth (learning/config.py plan_growth; issue 43 item 4).
    _p("plan_growth", F, "", 0.0, 0.0, 100.0, _LEARNER,
       "shared model: an episode's end plans only once some type has counted, since the last plan, this many times "
       "what it had then (0 = off: a plan after every episode)"),
)


# SPEC.md 1.2, section 13: the optional parameters are `start_at_rest` and every parameter from this one on (the
# shared-model learners' and the learner options added with them, `max_sweeps` and `in_place_sweeps` included).
OPTIONAL_FROM = "shared_model"


def _build() -> tuple[ParamDef, ...]:
    out = []
    optional_from = next(i for i, row in enumerate(_ROWS) if row[0] == OPTIONAL_FROM)
    for index, (name, kind, unit, default, low, high, refused, learner, doc, sim_only) in enumerate(_ROWS):
        if kind == ParamType.F32:  # an agent stores f32: the table says what it sends
            default, low, high = f32(default), f32(low), f32(high)
        out.append(ParamDef(index, name, kind, unit, float(default), float(low), float(high), refused, learner, doc,
                            sim_only, sim_only or index >= optional_from))
    return tuple(out)


PARAMS: tuple[ParamDef, ...] = _build()
PARAM_COUNT = len(PARAMS)
BY_NAME: dict[str, ParamDef] = {p.name: p for p in PARAMS}


def param(name: str) -> ParamDef:
    """The definition of a parameter by its wire name; KeyError if there is none."""
    return BY_NAME[name]
