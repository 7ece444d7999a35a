"""`dive run`: the main job. Connect, set parameters, learn, record to MCAP, show it live if asked."""

from __future__ import annotations

import contextlib
import dataclasses
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated
from urllib.parse import urlencode

import typer

from groundstation.cli import live_views
from groundstation.cli import view as view_cli
from groundstation.cli.common import UrlArg, err, one_line_errors
from groundstation.cli.pane_keys import AckKey
from groundstation.cli.signals import stop_on_signals
from groundstation.cli.validate import UsageError, check_presets, parse_speed
from groundstation.run.alarm_limits import DEPTH_LIMIT_M, LINK_LOST_S
from groundstation.safe_output import printable
from groundstation.session.handoff import Handoff
from groundstation.session.keys import KeyFileOption, resolve_key
from groundstation.view.options import Viewer, ranged

U32_MAX = 2**32 - 1  # CMD_START's max_episodes and the simulator's seed are U32

VIEW_HANDOFF_FRAMES = 65_536  # frames waiting for the live view before the newest are not shown (and counted)

if TYPE_CHECKING:
    from groundstation.links.runs import RunInfo
    from groundstation.run.status import RunStatus
    from groundstation.view.foxglove.live import FoxgloveLive


@one_line_errors
def run_command(
    url: UrlArg = None,
    episodes: Annotated[int, typer.Option(callback=ranged(0, U32_MAX), metavar="N",
                                          help="stop after this many completed episodes of the run, counted "
                                               "across learner restarts (0 = until Ctrl-C)")] = 0,
    speed: Annotated[str | None, typer.Option(help="built-in virtual agent only: time factor or 'max'")] = None,
    seed: Annotated[int | None, typer.Option(callback=ranged(0, U32_MAX), metavar="N",
                                             help="built-in virtual agent only: random seed")] = None,
    preset: Annotated[str | None, typer.Option(
        help="built-in virtual agent only: plant preset, paper (default) or hardware")] = None,
    learner: Annotated[str | None, typer.Option(
        help="built-in virtual agent only: learner preset, paper (default), shared (paper plant), "
             "shared-z20-bins7-diff8-term100-vpen1 (hardware plant), ...; a wrong name lists them all")] = None,
    viewer: view_cli.RunViewerOption = None,
    rrd: Annotated[Path | None, typer.Option(help="also save the live Rerun stream to this .rrd file")] = None,
    web_port: view_cli.WebPortOption = 9090,
    grpc_port: view_cli.GrpcPortOption = 9876,
    target_depth: Annotated[float | None, typer.Option(help="target depth z_d \\[m]")] = None,
    z_tol: Annotated[float | None, typer.Option(help="half-height of the learning region \\[m]")] = None,
    zdot_tol: Annotated[float | None, typer.Option(help="velocity bound of the learning region \\[m/s]")] = None,
    success_time: Annotated[float | None, typer.Option(
        help="time in the region that counts as success \\[s]")] = None,
    param: Annotated[list[str] | None, typer.Option(help="NAME=VALUE, any agent parameter (repeatable)")] = None,
    params: Annotated[Path | None, typer.Option(
        help="file of parameters: JSON or `name = value` lines; its \\[plant] table (dive fit) goes to a sim:// "
             "agent's simulator")] = None,
    out_path: Annotated[Path | None, typer.Option("--out", help="recording directory, or a .mcap file name")] = None,
    split_mb: Annotated[float, typer.Option(
        callback=ranged(0), metavar="MB",
        help="start a new file (NAME-part002.mcap, ...) after this many MB on disk (0 = never)")] = 0.0,
    split_minutes: Annotated[float, typer.Option(
        callback=ranged(0), metavar="MIN",
        help="start a new file after this many minutes (0 = never)")] = 0.0,
    # One flag each, not --reconnect/--no-reconnect: a second name column made the help's option column 41 wide
    no_reconnect: Annotated[bool, typer.Option(
        "--no-reconnect", help="end at a link loss (default: reconnect and backfill the gap)")] = False,
    no_dumps: Annotated[bool, typer.Option(
        "--no-dumps", help="the agent sends no values and policy after every episode (recorded by default: the "
                           "replay's heatmaps)")] = False,
    history_minutes: Annotated[float, typer.Option(
        callback=ranged(0), metavar="MIN",
        help="telemetry a tool attaching late (dive view) is given first, besides the episode table and the "
             "last dumps \\[min] (at most 2 MiB of it)")] = 2.0,
    alarm_depth: Annotated[float, typer.Option(
        callback=ranged(0), metavar="M", help="alarm when the agent is deeper than this \\[m]")] = DEPTH_LIMIT_M,
    alarm_link_lost: Annotated[float, typer.Option(
        callback=ranged(0), metavar="S",
        help="alarm when the agent has sent nothing, or the link has been lost, for this long \\[s]")]
        = LINK_LOST_S,
    key_file: KeyFileOption = None,
    foxglove: view_cli.FoxgloveOption = None,
) -> None:
    """Connect, set parameters, start learning and record everything to MCAP until N episodes or Ctrl-C."""
    from groundstation.cli.progress import RunDisplay
    from groundstation.recording.recorder import RecorderConfig
    from groundstation.run.alarms import AlarmConfig
    from groundstation.run.config import RunConfig, load_params_file
    from groundstation.run.history import HistoryConfig
    from groundstation.run.job import run
    from groundstation.session.agent_session import SessionConfig

    if speed is not None:
        parse_speed(speed)  # now, not 10 s later inside the virtual agent
    check_presets(preset, learner)
    url = _with_sim_options(url, speed=speed, seed=seed, preset=preset, learner=learner)
    values: dict[str, str] = load_params_file(params) if params else {}
    if params is not None:
        url = _with_plant_table(url, params)
    for name, value in (("target_depth_m", target_depth), ("z_tol_m", z_tol), ("zdot_tol_mps", zdot_tol),
                        ("success_time_s", success_time)):
        if value is not None:
            values[name] = str(value)
    for item in param or []:
        name, sep, raw = item.partition("=")
        if not sep:
            raise typer.BadParameter(f"expected NAME=VALUE, got {item!r}", param_hint="--param")
        values[name.strip()] = raw.strip()
    if out_path is not None and out_path.suffix == ".mcap":
        recorder = RecorderConfig(directory=out_path.parent, path=out_path)
    else:
        recorder = RecorderConfig(directory=out_path or Path("recordings"))
    recorder = RecorderConfig(recorder.directory, recorder.path, int(split_mb * 1e6), split_minutes * 60.0)
    key = resolve_key(key_file)
    # Bound before the agent is started: a port in use is one line, not a virtual agent started for nothing.
    fox = live_views.open_foxglove(foxglove, name=f"dive run {url}") if foxglove is not None else None
    view = live_views.open_live_view(viewer, rrd, web_port, name=url, headless_default=Viewer.NONE,
                                   grpc_port=grpc_port)
    config = RunConfig(url=url, episodes=episodes, params=values, recorder=recorder,
                       session=SessionConfig(reconnect=not no_reconnect, key=key),
                       dumps_each_episode=not no_dumps,
                       history=HistoryConfig(window_s=history_minutes * 60.0),
                       alarms=AlarmConfig(link_lost_s=alarm_link_lost, silent_s=alarm_link_lost, depth_m=alarm_depth))
    stop, signalled, ack = threading.Event(), list[str](), threading.Event()
    finished: list[RunInfo] = []  # the run over, its web viewer up: still announced, so `dive status` says where
    with stop_on_signals(stop, signalled), live_views.closing_foxglove(fox), \
            live_views.closing_view(view, signalled, lambda: _withdraw(finished)):
        # the live view is fed from a thread of its own: a slow viewer never holds up the session that records
        rerun = Handoff(view, VIEW_HANDOFF_FRAMES, "dive-rerun-publish") if view is not None else None
        try:
            with RunDisplay(err, episodes, f"connecting to {url}", virtual=url.startswith("sim://")) as display, \
                    AckKey(ack) if display.live else contextlib.nullcontext():
                show = display.show if fox is None else _attaching(display.show, fox, key)
                # Foxglove publishes from the run's own session: the frames, commands and alarms the recording gets
                result = run(config, show, stop=stop, listeners=[display, *([rerun] if rerun is not None else []),
                                                                 *([fox.listener] if fox is not None else [])],
                             ack=ack)
        finally:
            if rerun is not None:
                rerun.close(5.0)  # what is queued reaches the view before it closes
        if rerun is not None and (rerun.failure or rerun.dropped):
            err.print(f"the live view {'stopped: ' + rerun.failure if rerun.failure else 'fell behind'}"
                      f"{f' ({rerun.dropped} frames not shown)' if rerun.dropped else ''}; the recording is complete",
                      style="yellow", soft_wrap=True)
        if view is not None and view.address and not signalled and result.announced is not None:
            finished.append(_announce_finished(result.announced, view.address, result.paths))
        # After the status line has ended (a path written under a live display was glued to its last line), before
        # a served web viewer waits: the path is printed however the run ends.
        for path in result.paths:
            typer.echo(printable(path))
    if result.paths:
        # A split recording: all its parts (zero-padded, so the shell's order is part order), not the last one alone
        shown = result.paths[-1] if len(result.paths) == 1 else \
            result.paths[0].with_name(result.paths[0].name.replace("-part001.mcap", "-part*.mcap"))
        err.print(f"next: dive log info {shown}\n      dive replay {shown}"
                  + ("" if view is not None else "\n      (dive run --viewer web shows the run live in a browser)"),
                  style="dim")
    if result.lost:
        err.print(f"{result.lost} samples lost: the agent's log no longer held them", style="yellow")
    if result.still_missing - result.lost:
        err.print(f"{result.still_missing - result.lost} samples not backfilled though the agent's log still "
                  "holds them (the link did not bring them in time)", style="yellow")
    if result.tools_dropped:
        err.print(f"{result.tools_dropped} tools attached to the run's hub were dropped for falling behind (each was "
                  "told why); the recording is not affected", style="yellow")
    if result.interrupted or signalled:
        did = f"; {result.status.stopped}" if result.status.stopped else ""
        err.print(f"stopped by {signalled[0] if signalled else 'Ctrl-C'}{did}; the recording is complete",
                  style="dim", soft_wrap=True)
        raise typer.Exit(130)  # the one convention: interrupted = 130, whatever was saved


def _announce_finished(info: RunInfo, viewer: str, paths: list[Path]) -> RunInfo:
    """The run announced again as finished, with its web viewer's address (best effort, as every announcement)."""
    from groundstation.links.runs import announce

    over = dataclasses.replace(info, state="finished", hub="", viewer=viewer, alarm="",
                               recording=str(paths[-1]) if paths else info.recording)
    with contextlib.suppress(OSError):
        announce(over)
    return over


def _withdraw(finished: list[RunInfo]) -> None:
    from groundstation.links.runs import withdraw

    for info in finished:
        withdraw(info)


def _attaching(show: Callable[[RunStatus], None], fox: FoxgloveLive,
               key: bytes | None) -> Callable[[RunStatus], None]:
    """The progress callback, which also attaches Foxglove's parameters and services to the run's hub once it is up
    (in the background: the run does not wait), as a tool: what Foxglove commands is the operator's, which the run
    does not undo."""
    attached: list[str] = []

    def progress(status: RunStatus) -> None:
        if status.hub and not attached:
            attached.append(status.hub)
            fox.attach_in_background(status.hub, key, status.messages.append)
        show(status)

    return progress


def _with_sim_options(url: str | None, **sim_options: object) -> str:
    """Add the built-in agent's options (`--speed`, `--seed`, ...) to a sim:// URL as query parameters."""
    from groundstation.links.runs import run_url_default

    url = run_url_default(url)
    options = {k: str(v) for k, v in sim_options.items() if v is not None}
    if not options:
        return url
    if not url.startswith("sim://"):
        flags = ", ".join(f"--{k}" for k in options)
        raise UsageError(f"{flags} apply to the built-in virtual agent (sim://) only")
    return _with_query(url, options)


def _with_query(url: str, options: dict[str, str]) -> str:
    return url + ("&" if "?" in url else "?") + urlencode(options)


def _with_plant_table(url: str, params: Path) -> str:
    """A parameter file's [plant] table (`dive fit`'s figures) goes to the simulator a sim:// URL starts.

    A real agent has its plant in the water: the table cannot apply, which one line says; the file's agent
    parameters are set all the same (what a user wants after `dive fit` wrote both kinds into one file).
    """
    from groundstation.session.paramfile import has_plant_table

    if not has_plant_table(params):
        return url
    if url.startswith("sim://"):
        return _with_query(url, {"plant": str(params.resolve())})
    err.print(f"{params}: its [plant] table is for a simulator (sim://) and cannot apply to {url}; its agent "
              "parameters are set", style="yellow", soft_wrap=True)
    return url
