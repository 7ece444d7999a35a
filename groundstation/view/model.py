"""What the live view and the replay show, as columns: protocol messages in, rows per entity out (no rerun here)."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from groundstation.session.dumps import DumpAssembler
from groundstation.view.entities import (
    ACTION_PATHS,
    CURVE_EPISODES,
    ENTITIES,
    MODE_PATHS,
    MOVING_AVERAGE_EPISODES,
    OUTCOME_NAMES,
    STATE_ENTITIES,
    SUCCESS_TIME_S,
    TEXT_LEVELS,
    Batch,
    Kind,
    Rows,
)
from groundstation.view.heatmap import (
    DEFAULT_GRID,
    Grid,
    dump_grid,
    policy_frame,
    policy_image,
    untried_cells,
    value_frame,
    value_image,
    value_range,
)
from protocol import DumpKind, FrameFlag, Message
from protocol import messages as m

# Re-exported: the live view and the replay take the catalogue with the model.
__all__ = ["ENTITIES", "Batch", "Kind", "Region", "Rows", "ViewModel"]


@dataclass(frozen=True, slots=True)
class Region:
    """The learning region of the current episode."""

    target_depth_m: float
    z_tol_m: float
    zdot_tol_mps: float


class ViewModel:
    """Turns the agent's messages into rows per entity; `take()` hands over what accumulated since the last call.

    The live view calls it per frame, the replay for a whole file: both then log the same rows the same way.
    """

    # The messages feed() makes rows of or keeps state from; it ignores every other one.
    SHOWN: tuple[type[Message], ...] = (m.Sample, m.EpisodeStart, m.EpisodeEnd, m.DumpChunk, m.Text, m.ParamValue,
                                        m.Heartbeat)

    def __init__(self) -> None:
        self._batch: Batch = {}
        self._agent_time_s = 0.0
        self._episode = 0
        self._step = 0
        self._depth_m = 0.0
        self._region: Region | None = None
        self._grid_params = dict(DEFAULT_GRID)  # the agent's defaults until its PARAM_VALUEs say otherwise
        self._zdot_cells = int(DEFAULT_GRID["zdot_cells"])
        self._grid_cells: int | None = None  # known from the first dump
        self._durations: deque[float] = deque(maxlen=MOVING_AVERAGE_EPISODES)
        self._curve: deque[tuple[int, float]] = deque(maxlen=CURVE_EPISODES)  # (episode, duration), by-episode curve
        self._generation = 0  # the learner's (SPEC 1.3 s. 6); 0 until named (never, by a 1.2 agent)
        self._last_start = 0  # the last episode started in this chapter
        self._dumps = DumpAssembler()
        self._values: NDArray[np.float32] | None = None  # the latest VALUES dump
        self._untried: NDArray[np.bool_] | None = None  # the states the latest POLICY dump says were never left
        self._backfilled = 0

    def count_backfilled(self) -> None:
        """A backfilled SAMPLE a replay passed over unfed (before its window): the count the window opens on."""
        self._backfilled += 1

    def take(self) -> Batch:
        batch, self._batch = self._batch, {}
        return batch

    def keep_state(self) -> None:
        """Drop the rows so far but the state a replay window opens on (`dive replay --from`): the latest value and
        policy heatmaps with their axes, the learning curve by episode, and the curve over agent time (one row per
        episode). Their times are the last ones before the window: the viewer shows them at its start."""
        batch, self._batch = self._batch, {}
        for path, rows in batch.items():
            if path.startswith("learning_curve/"):
                self._batch[path] = rows
            elif path.split("/")[0] in STATE_ENTITIES and rows.values:
                last = len(rows) - 1
                self._batch[path] = Rows([rows.agent_time_s[last]], [rows.host_time_ns[last]], [rows.episode[last]],
                                         [rows.step[last]], [rows.values[last]])

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
            level = TEXT_LEVELS.get(message.severity, "INFO")
            self._row("log/agent", (message.text, level), host_time_ns)
        elif isinstance(message, m.Heartbeat):
            if not replayed:  # the agent's state now, once a second: the battery and mode panels
                self._agent_time_s = message.uptime_ms / 1e3
                self._row("battery/battery_v", message.battery_mv / 1e3, host_time_ns)
                self._row(MODE_PATHS.get(message.mode, "mode/other"), float(message.mode), host_time_ns)
        elif isinstance(message, m.ParamValue):
            self._dumps.saw_parameter(message.name, message.value)  # the grid bounds a dump's size
            if message.name in self._grid_params and math.isfinite(message.value) and message.value > 0:
                self._grid_params[message.name] = message.value
                if message.name == "zdot_cells":
                    self._zdot_cells = int(message.value)

    def event(self, kind: str, host_time_ns: int, detail: str = "", data: dict[str, Any] | None = None) -> None:
        """A link life-cycle event or a user marker (live: LinkEvent; replay: the /event and /marker topics)."""
        if kind == "stats":  # the 1 Hz link statistics: plotted, not listed
            self.link_stats(host_time_ns, data or {})
            return
        text = f"{kind}: {detail}" if detail else kind
        level = "ERROR" if kind == "alarm" else "WARN" if kind in ("link_lost", "error") else "INFO"
        self._row("log/events", (text, level), host_time_ns)

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
        self._row("depth/z_up_m", -s.depth_m, host_time_ns)
        self._row("velocity/velocity_mps", s.velocity_mps, host_time_ns)
        self._row("actuator/actuator_deg", s.actuator_deg, host_time_ns)
        self._row("actuator/actuator_cmd_deg", s.actuator_cmd_deg, host_time_ns)
        self._row("reward/reward", s.reward, host_time_ns)
        if s.action in ACTION_PATHS:
            self._row(ACTION_PATHS[s.action], float(s.action), host_time_ns)
        region = self._region
        if region is not None:
            self._row("depth/target_z_up_m", -region.target_depth_m, host_time_ns)
            self._row("depth/region_top_z_up_m", -(region.target_depth_m - region.z_tol_m), host_time_ns)
            self._row("depth/region_bottom_z_up_m", -(region.target_depth_m + region.z_tol_m), host_time_ns)
            self._row("velocity/bound_min_mps", -region.zdot_tol_mps, host_time_ns)
            self._row("velocity/bound_max_mps", region.zdot_tol_mps, host_time_ns)
        cell = self._cell(s.state)
        self._row("value_function/current_cell", cell, host_time_ns)
        self._row("policy/current_cell", cell, host_time_ns)
        if replayed:
            self._backfilled += 1
            self._row("link/backfilled_samples", float(self._backfilled), host_time_ns)

    def samples(self, records: NDArray[np.void], host_time_ns: list[int], replayed: list[bool]) -> None:
        """Many SAMPLEs in a row (a replay's run between other messages), as columns: the rows feed() makes.

        `records` is the structured array of their payloads (groundstation.recording.columns.message_array); the rows,
        values and timelines are those of feeding each SAMPLE in turn (a test compares them).
        """
        count = len(records)
        if count == 0:
            return
        agent_s = (records["t_us"] / 1e6).tolist()
        episodes = records["episode"].tolist()
        steps = records["step"].tolist()

        def rows(path: str, values: list[Any], keep: list[int] | None = None) -> None:
            target = self._batch.get(path)
            if target is None:
                target = self._batch[path] = Rows()
            if keep is None:
                target.agent_time_s += agent_s
                target.host_time_ns += host_time_ns
                target.episode += episodes
                target.step += steps
            else:
                target.agent_time_s += [agent_s[i] for i in keep]
                target.host_time_ns += [host_time_ns[i] for i in keep]
                target.episode += [episodes[i] for i in keep]
                target.step += [steps[i] for i in keep]
            target.values += values

        rows("depth/z_up_m", (-records["depth_m"]).tolist())
        rows("velocity/velocity_mps", records["velocity_mps"].tolist())
        rows("actuator/actuator_deg", records["actuator_deg"].tolist())
        rows("actuator/actuator_cmd_deg", records["actuator_cmd_deg"].tolist())
        rows("reward/reward", records["reward"].tolist())
        actions = records["action"]
        for action, path in ACTION_PATHS.items():
            acted = np.flatnonzero(actions == action).tolist()
            if acted:
                rows(path, [float(action)] * len(acted), acted)
        region = self._region
        if region is not None:
            for path, value in (("depth/target_z_up_m", -region.target_depth_m),
                                ("depth/region_top_z_up_m", -(region.target_depth_m - region.z_tol_m)),
                                ("depth/region_bottom_z_up_m", -(region.target_depth_m + region.z_tol_m)),
                                ("velocity/bound_min_mps", -region.zdot_tol_mps),
                                ("velocity/bound_max_mps", region.zdot_tol_mps)):
                rows(path, [value] * count)
        cells = self._cells(records["state"])
        rows("value_function/current_cell", cells)
        rows("policy/current_cell", list(cells))
        again = [i for i, flag in enumerate(replayed) if flag]
        if again:
            first = self._backfilled + 1
            self._backfilled += len(again)
            rows("link/backfilled_samples", [float(n) for n in range(first, self._backfilled + 1)], again)
        self._agent_time_s, self._episode, self._step, self._depth_m = (agent_s[-1], episodes[-1], steps[-1],
                                                                      float(records["depth_m"][-1]))

    def _cells(self, states: NDArray[np.integer[Any]]) -> list[tuple[float, float, str]]:
        """_cell of many states."""
        zdot = self._zdot_cells
        cells = self._grid_cells
        state = states.astype(np.int64)
        x = (state % zdot + 0.5).tolist()
        y = (state // zdot + 0.5).tolist()
        labels = ["agent"] * len(x)
        if cells is not None:
            outside = np.flatnonzero(state >= cells).tolist()
            for i in outside:
                x[i], y[i], labels[i] = zdot / 2, -1.0, "outside"
        return list(zip(x, y, labels, strict=True))

    def _cell(self, state: int) -> tuple[float, float, str]:
        """Centre of the state's cell in heatmap pixels; the terminal state sits above the grid (below: the axis)."""
        zdot = self._zdot_cells
        cells = self._grid_cells
        if cells is not None and state >= cells:
            return (zdot / 2, -1.0, "outside")
        return (state % zdot + 0.5, state // zdot + 0.5, "agent")

    def _chapter(self, generation: int, episode: int, start: bool, host_time_ns: int) -> None:
        """A learner restart numbers the episodes from 1 again: the learning curves start afresh (one curve per
        chapter: the mean and the by-episode bars never mix two learners), and the log says where."""
        new = bool(generation and self._generation and generation != self._generation) or \
            (not generation and start and 0 < episode <= self._last_start)  # a 1.2 agent: its numbers went back
        self._generation = generation or self._generation
        if new:
            self._durations.clear()
            self._curve.clear()
            named = f"generation {generation}" if generation else "inferred: the agent sends no generation"
            self._row("log/events", (f"the learner restarted ({named}): a new chapter, its episodes numbered from 1; "
                                     "the learning curves start afresh", "WARN"), host_time_ns)
        if start:
            self._last_start = episode

    def _episode_start(self, e: m.EpisodeStart, host_time_ns: int) -> None:
        self._chapter(e.generation, e.episode, True, host_time_ns)
        self._agent_time_s = e.t_us / 1e6
        self._episode, self._step, self._depth_m = e.episode, 0, e.depth_m
        self._region = Region(e.target_depth_m, e.z_tol_m, e.zdot_tol_mps)
        self._row("depth/episode_start_z_up_m", -e.depth_m, host_time_ns)
        text = f"episode {e.episode} start at {e.depth_m:.3f} m, target {e.target_depth_m:.3f} m, " \
            f"p_explore {e.p_explore:.3f}"
        self._row("log/events", (text, "INFO"), host_time_ns)

    def _episode_end(self, e: m.EpisodeEnd, host_time_ns: int) -> None:
        self._chapter(e.generation, e.episode, False, host_time_ns)
        self._agent_time_s = e.t_us / 1e6
        self._episode = e.episode
        outcome = OUTCOME_NAMES.get(e.reason, "aborted")
        self._row(f"depth/episode_{outcome}_z_up_m", -self._depth_m, host_time_ns)
        text = f"episode {e.episode} {outcome} after {e.duration_s:.1f} s, {e.steps} steps, " \
            f"return {e.episode_return:.2f}, {e.successes} successes"
        self._row("log/events", (text, "INFO" if outcome == "success" else "WARN"), host_time_ns)
        if outcome != "aborted":  # an aborted episode says nothing about learning
            self._durations.append(e.duration_s)
            self._row("learning_curve/duration_s", e.duration_s, host_time_ns)
            self._row("learning_curve/moving_average_s", sum(self._durations) / len(self._durations), host_time_ns)
            self._row("learning_curve/success_line_s", SUCCESS_TIME_S, host_time_ns)
            self._curve.append((e.episode, e.duration_s))
            episodes, durations = zip(*self._curve, strict=True)
            self._row("learning_curve_by_episode/duration_s",
                      (np.asarray(episodes, np.float64), np.asarray(durations, np.float64)), host_time_ns)

    def _dump_chunk(self, chunk: m.DumpChunk, host_time_ns: int) -> None:
        dump = self._dumps.feed(chunk)
        if dump is None:
            return
        if dump.kind == DumpKind.VALUES:
            values = np.frombuffer(dump.data, "<f4")
            grid = self._grid(len(values))
            if grid is None:
                return
            self._grid_cells = len(values) - 1
            self._values = values
            self._value_rows(grid, host_time_ns)
        elif dump.kind == DumpKind.POLICY:
            actions = np.frombuffer(dump.data, np.uint8)
            grid = self._grid(len(actions))
            if grid is None:
                return
            self._grid_cells = len(actions) - 1
            self._row("policy/image", policy_image(actions, self._zdot_cells), host_time_ns)
            self._row("policy/frame", policy_frame(grid), host_time_ns)
            # The agent sends VALUES then POLICY: the values drawn again with the cells this policy says are untried
            self._untried = untried_cells(actions)
            if self._values is not None and len(self._values) == len(actions):
                self._value_rows(grid, host_time_ns)

    def _value_rows(self, grid: Grid, host_time_ns: int) -> None:
        values, untried = self._values, self._untried
        assert values is not None
        self._row("value_function/image", value_image(values, self._zdot_cells, untried), host_time_ns)
        self._row("value_function/frame", value_frame(grid, *value_range(values, self._zdot_cells, untried)),
                  host_time_ns)

    def _grid(self, states: int) -> Grid | None:
        """The grid a dump of `states` states covers; None when it holds not one row of cells."""
        region = self._region
        if region is None:
            params = self._grid_params
            region = Region(params["target_depth_m"], params["z_tol_m"], params["zdot_tol_mps"])
        return dump_grid(states, region.target_depth_m, region.z_tol_m, region.zdot_tol_mps,
                         int(self._grid_params["z_cells"]), self._zdot_cells)
