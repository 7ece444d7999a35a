"""The view's catalogue: every entity it draws, its kind and legend name, the timelines, and rows as columns."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Any

from protocol import Action, EndReason, Mode, Severity

SUCCESS_TIME_S = 300.0  # an episode that lasts this long is a success (paper V-A)
MOVING_AVERAGE_EPISODES = 50
# The by-episode curve is sent whole at each episode end (the viewer shows the latest one, on any timeline):
# bounded so a night of short episodes does not grow the recording by the square of their number.
CURVE_EPISODES = 1000


class Kind(Enum):
    SCALAR = "scalar"  # float per row
    POINT = "point"  # float per row, drawn as markers
    TEXT = "text"  # (text, level) per row
    IMAGE = "image"  # HxWx3 uint8 per row
    BOX = "box"  # (center_x, center_y, label) per row: the agent's cell on a heatmap
    FRAME = "frame"  # heatmap.Frame per row: a heatmap's axes, tick values and colour legend
    BARS = "bars"  # (episode numbers, durations) per row: the whole learning curve up to this episode


# Entity path -> (kind, legend name). The blueprint groups them by their first path component.
# The depth panel plots z up (= -depth): deeper is drawn lower, as the heatmaps draw it (a plot axis cannot flip).
ENTITIES: dict[str, tuple[Kind, str]] = {
    "depth/z_up_m": (Kind.SCALAR, "z up = -depth [m]"),
    "depth/target_z_up_m": (Kind.SCALAR, "target z up [m]"),
    "depth/region_top_z_up_m": (Kind.SCALAR, "learning region [m]"),  # one name: one legend entry for both edges
    "depth/region_bottom_z_up_m": (Kind.SCALAR, "learning region [m]"),
    "depth/episode_start_z_up_m": (Kind.POINT, "episode start"),
    "depth/episode_success_z_up_m": (Kind.POINT, "success"),
    "depth/episode_failure_z_up_m": (Kind.POINT, "failure"),
    "depth/episode_aborted_z_up_m": (Kind.POINT, "aborted"),
    "velocity/velocity_mps": (Kind.SCALAR, "velocity [m/s]"),
    "velocity/bound_min_mps": (Kind.SCALAR, "bound [m/s]"),
    "velocity/bound_max_mps": (Kind.SCALAR, "bound [m/s]"),
    "actuator/actuator_deg": (Kind.SCALAR, "actuator [deg]"),
    "actuator/actuator_cmd_deg": (Kind.SCALAR, "command [deg]"),
    # One series per action and per mode, named by it: the legend labels them (a plot axis shows only numbers)
    "action/decrease_volume": (Kind.POINT, "less volume (a1)"),
    "action/increase_volume": (Kind.POINT, "more volume (a2)"),
    "reward/reward": (Kind.SCALAR, "reward"),
    "battery/battery_v": (Kind.SCALAR, "battery [V]"),
    **{f"mode/{mode.name.lower()}": (Kind.POINT, mode.name) for mode in Mode},
    "mode/other": (Kind.POINT, "another mode"),
    "learning_curve/duration_s": (Kind.POINT, "duration [s]"),
    "learning_curve/moving_average_s": (Kind.SCALAR, f"{MOVING_AVERAGE_EPISODES}-episode mean [s]"),
    "learning_curve/success_line_s": (Kind.SCALAR, f"success time ({SUCCESS_TIME_S:.0f} s)"),
    "learning_curve_by_episode/duration_s": (Kind.BARS, "duration [s] per episode"),
    "value_function/image": (Kind.IMAGE, "v(s)"),
    "value_function/current_cell": (Kind.BOX, "agent"),
    "value_function/frame": (Kind.FRAME, "axes and legend"),
    "policy/image": (Kind.IMAGE, "policy"),
    "policy/current_cell": (Kind.BOX, "agent"),
    "policy/frame": (Kind.FRAME, "axes and legend"),
    "link/loss_ratio": (Kind.SCALAR, "loss"),
    "link/rtt_s": (Kind.SCALAR, "RTT [s]"),
    "link/backfilled_samples": (Kind.SCALAR, "backfilled samples"),
    "log/agent": (Kind.TEXT, "agent log"),
    "log/events": (Kind.TEXT, "episodes and link"),
}
TIMELINES = ("agent_time", "host_time", "episode", "step")
STATE_ENTITIES = ("value_function", "policy", "learning_curve_by_episode")  # what keep_state keeps the last of
MODE_PATHS = {int(mode): f"mode/{mode.name.lower()}" for mode in Mode}
ACTION_PATHS = {int(Action.DECREASE_VOLUME): "action/decrease_volume",
                int(Action.INCREASE_VOLUME): "action/increase_volume"}
OUTCOME_NAMES: dict[int, str] = {EndReason.SUCCESS: "success", EndReason.FAILURE: "failure",
                                 EndReason.ABORTED: "aborted"}
TEXT_LEVELS: dict[int, str] = {Severity.DEBUG: "DEBUG", Severity.INFO: "INFO", Severity.WARNING: "WARN",
                               Severity.ERROR: "ERROR"}  # rerun's TextLog level names


@dataclass(slots=True)
class Rows:
    """One entity's rows as columns: the four timelines and one value per row."""

    agent_time_s: list[float] = field(default_factory=list)
    host_time_ns: list[int] = field(default_factory=list)
    episode: list[int] = field(default_factory=list)
    step: list[int] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)

    def __len__(self) -> int:
        return len(self.values)


Batch = dict[str, Rows]  # entity path -> rows, in arrival order
