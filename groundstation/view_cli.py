"""Bodies of `dive view URL` and `dive replay FILE`: parse, call the view and replay code, one line per error."""

from __future__ import annotations

import os
import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated

import typer
from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

from groundstation import replay as rp
from groundstation.errors import GroundStationError
from groundstation.keys import KeyFileOption, resolve_key
from groundstation.links import make_link
from groundstation.mcap_io import RecordingContents
from groundstation.rerun_view import RerunView, ViewConfig, Viewer, attach_view
from groundstation.safe_output import in_markup, one_line
from groundstation.session import Session, SessionConfig
from groundstation.view_errors import ViewError

ViewerOption = Annotated[
    Viewer | None,
    typer.Option("--viewer", help="spawn: native viewer; web: serve the web viewer on --web-port; none. "
                 "Default: spawn with a display, else web (none when only --rrd is given)."),
]
WebPortOption = Annotated[int, typer.Option("--web-port", help="Port of the web viewer (--viewer web).")]
GrpcPortOption = Annotated[int, typer.Option("--grpc-port", help="Port of the Rerun data stream.")]


def _fail(message: str) -> typer.Exit:
    typer.echo(f"dive: {one_line(message)}", err=True)  # the prefix of every dive error (cli.py)
    return typer.Exit(1)


def default_viewer(viewer: Viewer | None, rrd: Path | None, headless_default: Viewer = Viewer.WEB) -> Viewer:
    """The viewer asked for; else none when only --rrd is given, else spawn with a display, else the given one."""
    if viewer is not None:
        return viewer
    if rrd is not None:
        return Viewer.NONE
    return Viewer.SPAWN if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") else headless_default


def open_live_view(viewer: Viewer | None, rrd: Path | None, web_port: int, name: str,
                   headless_default: Viewer = Viewer.WEB) -> RerunView | None:
    """The live view `dive run` attaches to its session, or None when neither a viewer nor a file is wanted."""
    chosen = default_viewer(viewer, rrd, headless_default)
    if chosen == Viewer.NONE and rrd is None:
        return None
    live = attach_view(ViewConfig(viewer=chosen, rrd=rrd, web_port=web_port), name=name)
    if live is not None and live.address:
        typer.echo(f"Rerun web viewer: {live.address}", err=True)
    return live


@contextmanager
def closing_view(live: RerunView | None) -> Iterator[None]:
    """Close the live view however the run ends; a served web viewer stays up until Ctrl-C first."""
    try:
        yield
    finally:
        if live is not None:
            if live.address:
                wait_for_interrupt(f"the run is over; the web viewer stays at {live.address}")
            live.close()


def _parse_speed(text: str) -> float | None:
    """`max` (None) or a positive factor; `10x` and `10` both mean ten times real time."""
    if text.strip().lower() == "max":
        return None
    try:
        speed = float(text.strip().lower().removesuffix("x"))
    except ValueError:
        speed = 0.0
    if speed <= 0:
        raise ViewError(f"bad speed {text!r}: give a factor such as 1, 10 or max")
    return speed


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def wait_for_interrupt(what: str) -> None:
    """Keep going (serving the web viewer, watching the agent) until Ctrl-C or SIGTERM, then return."""
    typer.echo(f"{what}; Ctrl-C to stop", err=True)
    try:
        while True:
            time.sleep(0.2)
    except KeyboardInterrupt:
        pass


def _progress_items(items: Iterator[rp.Item], progress: Progress, task: object) -> Iterator[rp.Item]:
    for i, item in enumerate(items, 1):
        if i % 2048 == 0:
            progress.update(task, completed=i)  # type: ignore[arg-type]
        yield item


def replay(
    file: Annotated[Path, typer.Argument(help="An MCAP recording made by `dive run` (a truncated one too).")],
    speed: Annotated[str, typer.Option("--speed", help="Play in agent time: 1, 10, ... or max.")] = "max",
    rrd: Annotated[Path | None, typer.Option("--rrd", help="Convert to this .rrd file (no viewer needed).")] = None,
    start: Annotated[str | None, typer.Option("--from", help="First episode (12) or time since start (90s, 5m).")]
    = None,
    end: Annotated[str | None, typer.Option("--to", help="Last episode (20) or time since start (30m, 1h).")] = None,
    viewer: ViewerOption = None,
    web_port: WebPortOption = 9090,
    grpc_port: GrpcPortOption = 9876,
) -> None:
    """Show a recording in the live view's layout, or convert it to .rrd with --rrd."""
    signal.signal(signal.SIGTERM, _interrupt)  # a service manager's stop is a Ctrl-C: clean shutdown
    try:
        factor = _parse_speed(speed)
        bounds = (rp.parse_bound(start) if start else None, rp.parse_bound(end) if end else None)
        if not file.is_file():
            raise ViewError(f"no such recording: {file}")
        config = ViewConfig(viewer=default_viewer(viewer, rrd), rrd=rrd, web_port=web_port, grpc_port=grpc_port)
        status = RecordingContents()
        items = rp.select(rp.read_items(file, status), *bounds)
        began = time.perf_counter()
        with RerunView.open(config, name=file.stem) as view:
            if view.address and factor is not None:
                typer.echo(f"Rerun web viewer: {view.address}")
            if factor is None:
                with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed} frames"),
                              TimeElapsedColumn(), transient=True, disable=not sys.stderr.isatty()) as progress:
                    task = progress.add_task(f"reading {in_markup(file.name)}", total=None)
                    batch, count = rp.convert(_progress_items(items, progress, task))
                view.send(batch)
            else:
                count = rp.play(items, view.feed_model, factor)
            rp.check_nonempty(count, file, status)
            if status.truncated:
                typer.echo(f"warning: {one_line(file)} was cut short (no footer); showing what was complete", err=True)
            if rrd is not None:
                view.flush()
                typer.echo(f"wrote {one_line(rrd)}: {count} frames in {time.perf_counter() - began:.2f} s")
            if view.address:
                if factor is None:
                    view.flush()
                    typer.echo(f"Rerun web viewer: {view.address}")
                wait_for_interrupt("serving the web viewer")
    except GroundStationError as e:
        raise _fail(str(e)) from None
    except KeyboardInterrupt:
        raise typer.Exit(130) from None


def view(
    url: Annotated[str | None, typer.Argument(help="The agent: tcp://, serial://, sim://... (default $DIVE_URL).")]
    = None,
    viewer: ViewerOption = None,
    rrd: Annotated[Path | None, typer.Option("--rrd", help="Also save the stream to this .rrd file.")] = None,
    web_port: WebPortOption = 9090,
    grpc_port: GrpcPortOption = 9876,
    key_file: KeyFileOption = None,
) -> None:
    """Watch the agent live in the Rerun view, without commanding it."""
    signal.signal(signal.SIGTERM, _interrupt)
    try:
        link = make_link(url)
        config = ViewConfig(viewer=default_viewer(viewer, None), rrd=rrd, web_port=web_port, grpc_port=grpc_port)
        with RerunView.open(config, name=link.url) as live:
            if live.address:
                typer.echo(f"Rerun web viewer: {live.address}")
            # signed too: a signing agent refuses an unsigned HELLO's follow-ups (PARAM_LIST) as UNAUTHORIZED
            with Session(link, SessionConfig(key=resolve_key(key_file)), listeners=[live]) as session:
                hello = session.agent_hello
                typer.echo(f"watching {one_line(hello.name) if hello else 'the agent'} at {one_line(link.url)}")
                wait_for_interrupt("watching")
    except GroundStationError as e:
        raise _fail(str(e)) from None
    except KeyboardInterrupt:
        raise typer.Exit(130) from None
