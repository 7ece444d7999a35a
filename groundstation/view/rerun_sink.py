"""The Rerun view (the one module importing rerun): blueprint, sinks (viewer, web, .rrd) and columnar logging."""

from __future__ import annotations

import os
import threading
import time
import uuid
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
from rerun.encodings import TimeInt

from groundstation.session.events import LinkEvent, Received, Sent
from groundstation.view.entities import ENTITIES, Batch, Kind, Rows
from groundstation.view.errors import ViewError
from groundstation.view.heatmap import AXIS_COLOUR, DEFAULT_GRID, SWATCH_RADIUS, Bounds, Frame, bounds, default_grid
from groundstation.view.model import ViewModel
from groundstation.view.native_viewer import ServedViewer, start_native_viewer
from groundstation.view.options import Viewer
from groundstation.view.web_server import WebViewerServer

APPLICATION_ID = "diving_agent"
SERIES_COLOURS: dict[str, tuple[int, int, int]] = {
    "depth/z_up_m": (40, 120, 220),
    "depth/target_z_up_m": (60, 180, 75),
    "depth/region_top_z_up_m": (150, 150, 150),
    "depth/region_bottom_z_up_m": (150, 150, 150),
    "depth/episode_start_z_up_m": (60, 180, 75),
    "depth/episode_success_z_up_m": (40, 200, 120),
    "depth/episode_failure_z_up_m": (230, 60, 60),
    "depth/episode_aborted_z_up_m": (200, 160, 40),
    "velocity/velocity_mps": (40, 120, 220),
    "velocity/bound_min_mps": (150, 150, 150),
    "velocity/bound_max_mps": (150, 150, 150),
    "actuator/actuator_deg": (40, 120, 220),
    "actuator/actuator_cmd_deg": (150, 150, 150),
    "action/decrease_volume": (230, 120, 30),
    "action/increase_volume": (40, 120, 220),
    "link/loss_ratio": (230, 60, 60),
    "link/rtt_s": (40, 120, 220),
    "link/backfilled_samples": (200, 160, 40),
    "learning_curve/duration_s": (40, 120, 220),
    "learning_curve/moving_average_s": (230, 120, 30),
    "learning_curve/success_line_s": (60, 180, 75),
    "learning_curve_by_episode/duration_s": (40, 120, 220),
}


@dataclass(frozen=True)
class ViewConfig:
    """Where the view goes. Memory limits keep a long session's viewer and served buffer bounded."""

    viewer: Viewer = Viewer.NONE
    rrd: Path | None = None
    web_port: int = 9090
    grpc_port: int = 9876
    viewer_memory_limit: str = "1GiB"  # the native viewer drops the oldest data past this
    server_memory_limit: str = "256MiB"  # the gRPC server's buffer for late-connecting viewers
    replay: bool = False  # a recording: the viewer opens paused on the first episode, not following the end

    @property
    def wanted(self) -> bool:
        return self.viewer != Viewer.NONE or self.rrd is not None


def _f32_free(value: float) -> float:
    """The value as written (0.04, not the f32 0.03999999910593033 the wire gives): layouts compare equal."""
    return float(f"{value:.6g}")


@dataclass(frozen=True)
class Layout:
    """What the layout's scales are made for: the agent's velocity bound and the heatmaps' extent."""

    zdot_tol_mps: float = _f32_free(DEFAULT_GRID["zdot_tol_mps"])
    heatmap: Bounds = bounds(default_grid())
    replay: bool = False
    first_episode_s: tuple[float, float] | None = None  # a replay's first episode in agent time, once seen

    def velocity_range_mps(self) -> tuple[float, float]:
        """Three times the learning region's bound: the bounds sit a third of the way out, and the plot's ticks
        (powers of ten) get room for a labelled value either side of zero (at +-1 bound: zero alone)."""
        return (-3.0 * self.zdot_tol_mps, 3.0 * self.zdot_tol_mps)

    def followed(self, batch: Batch) -> Layout:
        """This layout made for what `batch` shows (the agent's bound, a dump's grid)."""
        bound = batch.get("velocity/bound_max_mps")
        zdot_tol_mps = _f32_free(bound.values[-1]) if bound else self.zdot_tol_mps
        frames = batch.get("value_function/frame") or batch.get("policy/frame")
        heatmap = frames.values[-1].bounds if frames else self.heatmap
        return Layout(zdot_tol_mps, heatmap, self.replay, self._first_episode(batch))

    def _first_episode(self, batch: Batch) -> tuple[float, float] | None:
        """From the first episode's start to the next start (or the batch's last sample): a replay's opening view."""
        starts = batch.get("depth/episode_start_z_up_m")
        if not self.replay or self.first_episode_s is not None or not starts:
            return self.first_episode_s
        depth = batch.get("depth/z_up_m")
        first_s = starts.agent_time_s[0]
        end_s = starts.agent_time_s[1] if len(starts) > 1 else depth.agent_time_s[-1] if depth else first_s
        return (first_s, max(first_s, end_s))

    def time_panel(self) -> rrb.TimePanel:
        """Live: the viewer follows the newest data. Replay: paused, so the viewer opens at the timeline's start
        rather than its end, with the first episode selected (rerun 0.41's blueprint cannot place the cursor)."""
        if not self.replay:
            return rrb.TimePanel(timeline="agent_time", expanded=False)
        selection = None
        if self.first_episode_s is not None:
            start_s, end_s = self.first_episode_s
            selection = rrb.components.AbsoluteTimeRange(min=TimeInt(seconds=start_s), max=TimeInt(seconds=end_s))
        return rrb.TimePanel(timeline="agent_time", expanded=False, play_state="paused", loop_mode="off",
                             time_selection=selection)


def _heatmap_view(origin: str, name: str, layout: Layout) -> rrb.Spatial2DView:
    b = layout.heatmap
    return rrb.Spatial2DView(origin=origin, name=name,
                             visual_bounds=rrb.VisualBounds2D(x_range=(b.x_min, b.x_max), y_range=(b.y_min, b.y_max)))


# Each series is named (model.ENTITIES, sent by send_styles) and the legend shows the names: titles say what a panel
# is, never which colour is which (colour words were cut off at normal widths: "grey learning regi"). The legend
# sits in the top left corner, where the plots' newest data (at the right) does not go.
_LEGEND = rrb.PlotLegend(visible=True, corner=rrb.Corner2D.LeftTop)
_NO_LEGEND = rrb.PlotLegend(visible=False)  # one series, named by the title


def _plot(origin: str, name: str, legend: bool = True, **options: Any) -> rrb.TimeSeriesView:
    return rrb.TimeSeriesView(origin=origin, name=name, plot_legend=_LEGEND if legend else _NO_LEGEND, **options)


def blueprint(layout: Layout | None = None) -> rrb.Blueprint:
    """The shipped layout: time series on the left; learning curve, heatmaps (the most room) and logs on the right."""
    layout = layout or Layout()
    series = rrb.Vertical(
        _plot("depth", "Depth drawn downward (z up = -depth) [m]"),
        _plot("velocity", "Velocity [m/s]", axis_y=rrb.ScalarAxis(range=layout.velocity_range_mps())),
        _plot("actuator", "Actuator [deg]"),
        _plot("action", "Learner's action"),
        _plot("reward", "Reward", legend=False),
        _plot("link", "Link"),
        rrb.Horizontal(
            _plot("battery", "Battery [V]", legend=False),
            _plot("mode", "Mode"),
        ),
    )
    right = rrb.Vertical(
        rrb.Horizontal(
            rrb.BarChartView(origin="learning_curve_by_episode", name="Learning curve: duration [s] by episode number",
                             plot_legend=_NO_LEGEND),
            _plot("learning_curve", "Episode durations [s] over agent time"),
        ),
        rrb.Horizontal(
            _heatmap_view("value_function", "Value function v(depth down, velocity)", layout),
            _heatmap_view("policy", "Policy: greedy action per cell (depth down)", layout),
        ),
        rrb.Tabs(
            rrb.TextLogView(origin="log/agent", name="Agent log"),
            rrb.TextLogView(origin="log/events", name="Episodes and link events"),
        ),
        row_shares=[1, 2, 1],
    )
    return rrb.Blueprint(
        rrb.Horizontal(series, right, column_shares=[1, 1]),
        layout.time_panel(),
        collapse_panels=True,
    )


def new_recording(name: str) -> rr.RecordingStream:
    """A recording stream with no sink yet (set_sinks or save picks where it goes)."""
    rec = rr.RecordingStream(APPLICATION_ID, recording_id=uuid.uuid4(), send_properties=True)
    rec.send_recording_name(name)
    return rec


def send_styles(rec: rr.RecordingStream) -> None:
    """Static series names and colours, so every source looks the same."""
    for path, (kind, label) in ENTITIES.items():
        colour = SERIES_COLOURS.get(path)
        colours = [colour] if colour else None
        if kind == Kind.SCALAR:
            rec.log(path, rr.SeriesLines(names=[label], colors=colours), static=True)
        elif kind == Kind.POINT:
            rec.log(path, rr.SeriesPoints(names=[label], colors=colours, markers=["circle"], marker_sizes=[3.0]),
                    static=True)


def _indexes(rows: Rows) -> list[rr.TimeColumn]:
    return [
        rr.TimeColumn("agent_time", duration=np.asarray(rows.agent_time_s, np.float64)),
        rr.TimeColumn("host_time", timestamp=np.asarray(rows.host_time_ns, "datetime64[ns]")),
        rr.TimeColumn("episode", sequence=np.asarray(rows.episode, np.int64)),
        rr.TimeColumn("step", sequence=np.asarray(rows.step, np.int64)),
    ]


def _set_row_time(rec: rr.RecordingStream, rows: Rows, i: int) -> None:
    rec.set_time("agent_time", duration=rows.agent_time_s[i])
    rec.set_time("host_time", timestamp=np.datetime64(rows.host_time_ns[i], "ns"))
    rec.set_time("episode", sequence=rows.episode[i])
    rec.set_time("step", sequence=rows.step[i])


def send_batch(rec: rr.RecordingStream, batch: Batch) -> None:
    """Log every entity's rows as columns (one `send_columns` per entity): how live and replay both log."""
    for path, rows in batch.items():
        if not rows:
            continue
        kind = ENTITIES[path][0]
        if kind in (Kind.SCALAR, Kind.POINT):
            rec.send_columns(path, indexes=_indexes(rows),
                             columns=rr.Scalars.columns(scalars=np.asarray(rows.values, np.float64)))
        elif kind == Kind.TEXT:
            texts, levels = zip(*rows.values, strict=True)
            rec.send_columns(path, indexes=_indexes(rows), columns=rr.TextLog.columns(text=texts, level=levels))
        elif kind == Kind.BOX:
            xs, ys, labels = zip(*rows.values, strict=True)  # one pass in C, not one slice per row
            centres = np.column_stack((np.asarray(xs, np.float32), np.asarray(ys, np.float32)))
            rec.send_columns(path, indexes=_indexes(rows), columns=rr.Boxes2D.columns(
                centers=centres, half_sizes=np.full_like(centres, 0.5), labels=list(labels)))
        else:  # images, their frames, curves: a handful per episode, so row logging costs nothing here
            for i, value in enumerate(rows.values):
                _set_row_time(rec, rows, i)
                if kind == Kind.FRAME:
                    log_frame(rec, path, value)
                elif kind == Kind.BARS:
                    episodes, durations = value
                    rec.log(path, rr.BarChart(durations, abscissa=episodes, color=SERIES_COLOURS.get(path)))
                else:
                    rec.log(path, rr.Image(value, color_model="RGB", magnification_filter="Nearest"))
            rec.reset_time()


def log_frame(rec: rr.RecordingStream, path: str, frame: Frame) -> None:
    """A heatmap's axes and legend in the heatmap's own plane (one unit per cell), beside its image.

    Rerun draws a label centred under its point, in the point's colour: the texts are points of no size in the
    axis grey; the swatches carry their meaning as labels too (shown on hover), drawn by the texts under them.
    """
    texts, swatches = frame.texts, frame.swatches
    rec.log(f"{path}/axes", rr.LineStrips2D(frame.lines, colors=[AXIS_COLOUR], radii=rr.Radius.ui_points(1.0)))
    rec.log(f"{path}/texts", rr.Points2D([(t.x, t.y) for t in texts], radii=0.0, colors=[t.colour for t in texts],
                                          labels=[t.text for t in texts], show_labels=True))
    rec.log(f"{path}/legend", rr.Points2D([(s.x, s.y) for s in swatches], radii=SWATCH_RADIUS,
                                           colors=[s.colour for s in swatches], labels=[s.text for s in swatches],
                                           show_labels=False))  # a swatch of the colour, one cell across


def _has_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or os.name == "nt"


def open_sinks(rec: rr.RecordingStream, config: ViewConfig) -> ServedViewer | None:
    """Connect the stream to the configured viewer and file; returns the web viewer's server, if one was started."""
    sinks: list[Any] = []
    server: ServedViewer | None = None
    try:
        if config.viewer == Viewer.SPAWN:
            if not _has_display():
                raise ViewError("no display for the native viewer: use --viewer web on a headless machine")
            server = start_native_viewer(config.grpc_port, config.viewer_memory_limit, config.server_memory_limit)
            sinks.append(rr.GrpcSink(server.uri))
        elif config.viewer == Viewer.WEB:
            server = WebViewerServer.start(config.web_port, config.grpc_port, config.server_memory_limit)
            sinks.append(rr.GrpcSink(server.uri))
        if config.rrd is not None:
            config.rrd.parent.mkdir(parents=True, exist_ok=True)
            sinks.append(rr.FileSink(config.rrd))
        rec.set_sinks(*sinks, default_blueprint=blueprint(Layout(replay=config.replay)))
    except (ViewError, OSError, RuntimeError, ValueError) as e:
        if server is not None:
            server.close()
        if isinstance(e, ViewError):
            raise
        raise ViewError(f"cannot open the {config.viewer.value} viewer: {e}") from e
    rec.send_blueprint(blueprint(Layout(replay=config.replay)), make_active=True)
    send_styles(rec)
    return server


class RerunView:
    """The live view as a session listener: each received frame becomes rows, logged as they come.

    Use: `view = RerunView.open(ViewConfig(...), name)`; `session.add_listener(view)`; print `view.address`;
    `view.close()` at the end (or `with RerunView.open(...) as view:`).
    """

    def __init__(self, rec: rr.RecordingStream, server: ServedViewer | None = None, flush_interval_s: float = 0.1,
                 replay: bool = False) -> None:
        self._rec = rec
        self._server = server
        self._model = ViewModel()
        self._lock = threading.Lock()  # the session's reader thread and the caller may both feed it
        # Rows go out in columns at most every flush_interval_s: a send costs ~0.1 ms per entity, so a fast
        # replay or a backfill burst would otherwise spend its time in per-frame sends.
        self._flush_interval_s = flush_interval_s
        self._last_send_s = 0.0
        self._layout = Layout(replay=replay)  # what the blueprint sent last was made for
        self.address = server.address if server is not None else None
        self.notice: str | None = getattr(server, "notice", None)  # whom its port answers, if not the owner alone

    @classmethod
    def open(cls, config: ViewConfig, name: str = "live") -> RerunView:
        rec = new_recording(name)
        return cls(rec, open_sinks(rec, config), replay=config.replay)

    def _send_if_due(self) -> None:
        now_s = time.monotonic()
        if now_s - self._last_send_s >= self._flush_interval_s:
            self._last_send_s = now_s
            self._log(self._model.take())

    def on_received(self, received: Received) -> None:
        frame = received.frame
        with self._lock:
            self._model.feed(frame.message, received.host_time_ns, flags=frame.flags,
                             backfilled=received.backfilled)
            self._send_if_due()

    def on_sent(self, sent: Sent) -> None:
        pass  # commands show up through their effect on the agent (mode, episodes)

    def on_event(self, event: LinkEvent) -> None:
        with self._lock:
            self._model.event(event.kind.value, event.host_time_ns, event.detail, event.data)
            self._send_if_due()

    def feed_model(self, feed: Any) -> None:
        """Run `feed(model)` under the lock and log what it produced (the replay's paced playback)."""
        with self._lock:
            feed(self._model)
            self._send_if_due()

    def send(self, batch: Batch) -> None:
        """Log rows made elsewhere (a whole converted recording) in columns."""
        with self._lock:
            self._log(batch)

    def _log(self, batch: Batch) -> None:
        layout = self._layout.followed(batch)
        if layout != self._layout:
            # The velocity scale and the heatmaps' bounds follow the agent's bound and grid. A new layout replaces
            # one the user rearranged, so it is sent only when they change (the agent's defaults need none).
            self._layout = layout
            self._rec.send_blueprint(blueprint(layout), make_active=True)
        send_batch(self._rec, batch)

    def flush(self) -> None:
        with self._lock:
            self._log(self._model.take())
        self._rec.flush()

    def close(self) -> None:
        try:
            self.flush()
            self._rec.disconnect()
        finally:
            if self._server is not None:
                self._server.close()

    def __enter__(self) -> RerunView:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def attach_view(config: ViewConfig, name: str = "live") -> RerunView | None:
    """What `dive run` calls: a listener to add to the session, or None when neither viewer nor file is wanted."""
    return RerunView.open(config, name) if config.wanted else None
