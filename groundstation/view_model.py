"""What the live view and the replay show, as columns: protocol messages in, rows per entity out (no rerun here)."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from enum import Enum
from typing import Any

import numpy as np
from numpy.typing import NDArray

from groundstation.dumps import DumpAssembler
from protocol import Action, DumpKind, EndReason, FrameFlag, Message, Severity
from protocol import messages as m

SUCCESS_TIME_S = 300.0  # an episode that lasts this long is a success (paper V-A)
MOVING_AVERAGE_EPISODES = 50
DEFAULT_ZDOT_CELLS = 10  # velocity cells per grid row until the agent's parameters or a dump say otherwise


class Kind(Enum):
    SCALAR = "scalar"  # float per row
    POINT = "point"  # float per row, drawn as markers
    TEXT = "text"  # (text, level) per row
    IMAGE = "image"  # HxWx3 uint8 per row
    BOX = "box"  # (center_x, center_y, label) per row: the agent's cell on a heatmap


# Entity path -> (kind, legend name). The blueprint groups them by their first path component.
ENTITIES: dict[str, tuple[Kind, str]] = {
    "depth/depth_m": (Kind.SCALAR, "depth [m]"),
    "depth/target_depth_m": (Kind.SCALAR, "target [m]"),
    "depth/region_min_m": (Kind.SCALAR, "region top [m]"),
    "depth/region_max_m": (Kind.SCALAR, "region bottom [m]"),
    "depth/episode_start_m": (Kind.POINT, "episode start"),
    "depth/episode_success_m": (Kind.POINT, "success"),
    "depth/episode_failure_m": (Kind.POINT, "failure"),
    "depth/episode_aborted_m": (Kind.POINT, "aborted"),
    "velocity/velocity_mps": (Kind.SCALAR, "velocity [m/s]"),
    "velocity/bound_min_mps": (Kind.SCALAR, "bound [m/s]"),
    "velocity/bound_max_mps": (Kind.SCALAR, "bound [m/s]"),
    "actuator/actuator_deg": (Kind.SCALAR, "actuator [deg]"),
    "actuator/actuator_cmd_deg": (Kind.SCALAR, "command [deg]"),
    "action/action": (Kind.POINT, "action (0 less volume, 1 more)"),
    "reward/reward": (Kind.SCALAR, "reward"),
    "learning_curve/duration_s": (Kind.POINT, "duration [s]"),
    "learning_curve/moving_average_s": (Kind.SCALAR, f"{MOVING_AVERAGE_EPISODES}-episode mean [s]"),
    "learning_curve/success_line_s": (Kind.SCALAR, f"{SUCCESS_TIME_S:.0f} s"),
    "value_function/image": (Kind.IMAGE, "v(s)"),
    "value_function/current_cell": (Kind.BOX, "agent"),
    "policy/image": (Kind.IMAGE, "policy"),
    "policy/current_cell": (Kind.BOX, "agent"),
    "link/loss_ratio": (Kind.SCALAR, "loss"),
    "link/rtt_s": (Kind.SCALAR, "RTT [s]"),
    "link/backfilled_samples": (Kind.SCALAR, "backfilled samples"),
    "log/agent": (Kind.TEXT, "agent log"),
    "log/events": (Kind.TEXT, "episodes and link"),
}
TIMELINES = ("agent_time", "host_time", "episode", "step")
_OUTCOME: dict[int, str] = {EndReason.SUCCESS: "success", EndReason.FAILURE: "failure", EndReason.ABORTED: "aborted"}
_LEVELS: dict[int, str] = {Severity.DEBUG: "DEBUG", Severity.INFO: "INFO", Severity.WARNING: "WARN",
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


@dataclass(frozen=True, slots=True)
class Region:
    """The learning region of the current episode."""

    target_depth_m: float
    z_tol_m: float
    zdot_tol_mps: float


def _colormap(unit: NDArray[np.float64]) -> NDArray[np.uint8]:
    """Viridis-like colours for values in 0..1 (five anchors, linear in between)."""
    anchors = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)
    pos = np.clip(unit, 0.0, 1.0) * (len(anchors) - 1)
    low = np.minimum(pos.astype(int), len(anchors) - 2)
    frac = (pos - low)[..., None]
    return (anchors[low] * (1 - frac) + anchors[low + 1] * frac).astype(np.uint8)


_POLICY_COLOURS = {0: (230, 120, 30), 1: (40, 120, 220)}  # decrease volume (sink) / increase (rise)
_UNTRIED = (90, 90, 90)


def value_image(values: NDArray[np.float32], zdot_cells: int) -> NDArray[np.uint8]:
    """v(s) over the grid (rows: depth cells, shallow on top; columns: velocity cells, rising on the left)."""
    cells = values[: (len(values) - 1) // zdot_cells * zdot_cells].astype(np.float64)  # drop the terminal state
    low, high = float(np.min(cells)), float(np.max(cells))
    unit = (cells - low) / (high - low) if high > low else np.zeros_like(cells)
    return _colormap(unit.reshape(-1, zdot_cells))


def policy_image(actions: NDArray[np.uint8], zdot_cells: int) -> NDArray[np.uint8]:
    cells = actions[: (len(actions) - 1) // zdot_cells * zdot_cells]
    image = np.empty((len(cells), 3), np.uint8)
    image[:] = _UNTRIED
    for action, colour in _POLICY_COLOURS.items():
        image[cells == action] = colour
    return image.reshape(-1, zdot_cells, 3)


class ViewModel:
    """Turns the agent's messages into rows per entity; `take()` hands over what accumulated since the last call.

    The live view calls it per frame, the replay for a whole file: both then log the same rows the same way.
    """

    def __init__(self) -> None:
        self._batch: Batch = {}
        self._agent_time_s = 0.0
        self._episode = 0
        self._step = 0
        self._depth_m = 0.0
        self._region: Region | None = None
        self._zdot_cells = DEFAULT_ZDOT_CELLS
        self._grid_cells: int | None = None  # known from the first dump
        self._durations: deque[float] = deque(maxlen=MOVING_AVERAGE_EPISODES)
        self._dumps = DumpAssembler()
        self._backfilled = 0

    def take(self) -> Batch:
        batch, self._batch = self._batch, {}
        return batch

    def _row(self, path: str, value: Any, host_time_ns: int) -> None:
        rows = self._batch.get(path)
        if rows is None:
            rows = self._batch[path] = Rows()
        rows.agent_time_s.append(self._agent_time_s)
        rows.host_time_ns.append(host_time_ns)
        rows.episode.append(self._episode)
        rows.step.append(self._step)
        rows.values.append(value)

    # ------------------------------------------------------------ inputs

    def feed(self, message: Message, host_time_ns: int, *, flags: int = 0, backfilled: bool = False) -> None:
        """One received frame's message (as the session or the recording's raw frames give it)."""
        replayed = backfilled or bool(flags & FrameFlag.REPLAYED)
        if isinstance(message, m.Sample):
            self._sample(message, host_time_ns, replayed)
        elif isinstance(message, m.EpisodeStart):
            self._episode_start(message, host_time_ns)
        elif isinstance(message, m.EpisodeEnd):
            self._episode_end(message, host_time_ns)
        elif isinstance(message, m.DumpChunk):
            self._dump_chunk(message, host_time_ns)
        elif isinstance(message, m.Text):
            self._agent_time_s = message.t_us / 1e6
            level = _LEVELS.get(message.severity, "INFO")
            self._row("log/agent", (message.text, level), host_time_ns)
        elif isinstance(message, m.ParamValue):
            self._dumps.saw_parameter(message.name, message.value)  # the grid bounds a dump's size
            if message.name == "zdot_cells" and message.value >= 1:
                self._zdot_cells = int(message.value)

    def event(self, kind: str, host_time_ns: int, detail: str = "", data: dict[str, Any] | None = None) -> None:
        """A link life-cycle event or a user marker (live: LinkEvent; replay: the /event and /marker topics)."""
        if kind == "stats":  # the 1 Hz link statistics: plotted, not listed
            self.link_stats(host_time_ns, data or {})
            return
        text = f"{kind}: {detail}" if detail else kind
        self._row("log/events", (text, "WARN" if kind in ("link_lost", "error") else "INFO"), host_time_ns)

    def link_stats(self, host_time_ns: int, stats: dict[str, Any]) -> None:
        """The ground station's link statistics: live STATS events and the /link topic carry
        {"link": LinkStats.snapshot(), "clock": ...}; a bare snapshot is accepted too."""
        link = stats.get("link")
        stats = link if isinstance(link, dict) else stats
        loss = stats.get("loss_fraction")
        if isinstance(loss, int | float):
            self._row("link/loss_ratio", float(loss), host_time_ns)
        rtt_ms = stats.get("rtt_median_ms")
        if isinstance(rtt_ms, int | float) and math.isfinite(rtt_ms):
            self._row("link/rtt_s", rtt_ms / 1e3, host_time_ns)

    # ------------------------------------------------------------ per message

    def _sample(self, s: m.Sample, host_time_ns: int, replayed: bool) -> None:
        self._agent_time_s = s.t_us / 1e6
        self._episode, self._step, self._depth_m = s.episode, s.step, s.depth_m
        self._row("depth/depth_m", s.depth_m, host_time_ns)
        self._row("velocity/velocity_mps", s.velocity_mps, host_time_ns)
        self._row("actuator/actuator_deg", s.actuator_deg, host_time_ns)
        self._row("actuator/actuator_cmd_deg", s.actuator_cmd_deg, host_time_ns)
        self._row("reward/reward", s.reward, host_time_ns)
        if s.action != Action.NONE:
            self._row("action/action", float(s.action), host_time_ns)
        region = self._region
        if region is not None:
            self._row("depth/target_depth_m", region.target_depth_m, host_time_ns)
            self._row("depth/region_min_m", region.target_depth_m - region.z_tol_m, host_time_ns)
            self._row("depth/region_max_m", region.target_depth_m + region.z_tol_m, host_time_ns)
            self._row("velocity/bound_min_mps", -region.zdot_tol_mps, host_time_ns)
            self._row("velocity/bound_max_mps", region.zdot_tol_mps, host_time_ns)
        cell = self._cell(s.state)
        self._row("value_function/current_cell", cell, host_time_ns)
        self._row("policy/current_cell", cell, host_time_ns)
        if replayed:
            self._backfilled += 1
            self._row("link/backfilled_samples", float(self._backfilled), host_time_ns)

    def _cell(self, state: int) -> tuple[float, float, str]:
        """Centre of the state's cell in heatmap pixels; the terminal state sits under the grid."""
        zdot = self._zdot_cells
        cells = self._grid_cells
        if cells is not None and state >= cells:
            rows = cells // zdot
            return (zdot / 2, rows + 1.0, "outside")
        return (state % zdot + 0.5, state // zdot + 0.5, "agent")

    def _episode_start(self, e: m.EpisodeStart, host_time_ns: int) -> None:
        self._agent_time_s = e.t_us / 1e6
        self._episode, self._step, self._depth_m = e.episode, 0, e.depth_m
        self._region = Region(e.target_depth_m, e.z_tol_m, e.zdot_tol_mps)
        self._row("depth/episode_start_m", e.depth_m, host_time_ns)
        text = f"episode {e.episode} start at {e.depth_m:.3f} m, target {e.target_depth_m:.3f} m, " \
            f"p_explore {e.p_explore:.3f}"
        self._row("log/events", (text, "INFO"), host_time_ns)

    def _episode_end(self, e: m.EpisodeEnd, host_time_ns: int) -> None:
        self._agent_time_s = e.t_us / 1e6
        self._episode = e.episode
        outcome = _OUTCOME.get(e.reason, "aborted")
        self._row(f"depth/episode_{outcome}_m", self._depth_m, host_time_ns)
        text = f"episode {e.episode} {outcome} after {e.duration_s:.1f} s, {e.steps} steps, " \
            f"return {e.episode_return:.2f}, {e.successes} successes"
        self._row("log/events", (text, "INFO" if outcome == "success" else "WARN"), host_time_ns)
        if outcome != "aborted":  # an aborted episode says nothing about learning
            self._durations.append(e.duration_s)
            self._row("learning_curve/duration_s", e.duration_s, host_time_ns)
            self._row("learning_curve/moving_average_s", sum(self._durations) / len(self._durations), host_time_ns)
            self._row("learning_curve/success_line_s", SUCCESS_TIME_S, host_time_ns)

    def _dump_chunk(self, chunk: m.DumpChunk, host_time_ns: int) -> None:
        dump = self._dumps.feed(chunk)
        if dump is None:
            return
        if dump.kind == DumpKind.VALUES:
            values = np.frombuffer(dump.data, "<f4")
            self._grid_cells = len(values) - 1
            self._row("value_function/image", value_image(values, self._zdot_cells), host_time_ns)
        elif dump.kind == DumpKind.POLICY:
            actions = np.frombuffer(dump.data, np.uint8)
            self._grid_cells = len(actions) - 1
            self._row("policy/image", policy_image(actions, self._zdot_cells), host_time_ns)
