"""Bodies of `dive view URL` and `dive replay FILE`: parse, call the view and replay code, one line per error."""

from __future__ import annotations

import signal
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from groundstation.cli.live_views import (
    closing_foxglove,
    default_viewer,
    open_foxglove,
    say_where,
    viewer_ports,
    wait_for_interrupt,
)
from groundstation.cli.validate import UsageError, parse_speed
from groundstation.errors import GroundStationError
from groundstation.safe_output import in_markup, one_line
from groundstation.session.keys import KeyFileOption, resolve_key
from groundstation.view.errors import ViewError
from groundstation.view.options import (
    FoxgloveOption,
    GrpcPortOption,
    RunViewerOption,
    Viewer,
    ViewerOption,
    WebPortOption,
)

if TYPE_CHECKING:  # Rerun, mcap, foxglove and the replay code are imported by the commands that use them
    from rich.progress import Progress

    from groundstation.view.replay_items import Item
    from groundstation.view.rerun_sink import RerunView

__all__ = ["FoxgloveOption", "GrpcPortOption", "RunViewerOption", "ViewerOption", "WebPortOption", "replay", "view"]


def _fail(message: str, code: int = 1) -> typer.Exit:
    typer.echo(f"dive: {one_line(message)}", err=True)  # the prefix of every dive error (cli.py)
    return typer.Exit(code)


@contextmanager
def _one_line_errors() -> Iterator[None]:
    """Our errors become one line on stderr and exit code 1 (bad usage: 2); Ctrl-C before the end exits 130."""
    try:
        yield
    except UsageError as e:
        raise _fail(str(e), 2) from None
    except GroundStationError as e:
        raise _fail(str(e)) from None
    except KeyboardInterrupt:
        raise typer.Exit(130) from None


@contextmanager
def _removed_on_error(path: Path | None) -> Iterator[None]:
    """A failed conversion (an empty window, a file with no frames) leaves no partial .rrd behind."""
    try:
        yield
    except GroundStationError:
        if path is not None:
            path.unlink(missing_ok=True)
        raise


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _progress_items(items: Iterator[Item], progress: Progress, task: object) -> Iterator[Item]:
    for i, item in enumerate(items, 1):
        if i % 2048 == 0:
            progress.update(task, completed=i)  # type: ignore[arg-type]
        yield item


def replay(
    files: Annotated[list[Path], typer.Argument(
        help="An MCAP recording made by `dive run` (a truncated one too), the parts of a split one, or their folder.",
        show_default=False)],
    speed: Annotated[str, typer.Option("--speed", help="Play in agent time: 1, 10, ... or max.")] = "max",
    rrd: Annotated[Path | None, typer.Option("--rrd", help="Convert to this .rrd file (no viewer needed).")] = None,
    start: Annotated[str | None, typer.Option("--from", help=(
        "First episode (12; after a learner restart 2:5, chapter 2's episode 5, as dive log info numbers the "
        "chapters) or time since start (90s, 5m)."))] = None,
    end: Annotated[str | None, typer.Option("--to", help="Last episode (20, or 2:8) or time since start (30m, 1h).")
                   ] = None,
    viewer: ViewerOption = None,
    web_port: WebPortOption = 9090,
    grpc_port: GrpcPortOption = 9876,
) -> None:
    """Show a recording in the live view's layout, or convert it to .rrd with --rrd.

    The parts of a split recording (several files, or their folder) play as one timeline of agent time.
    """
    signal.signal(signal.SIGTERM, _interrupt)  # a service manager's stop is a Ctrl-C: clean shutdown
    stopped = False
    with _one_line_errors():
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        from groundstation.mcap_io import RecordingContents
        from groundstation.recording.files import expand
        from groundstation.view import replay as rp
        from groundstation.view import replay_convert as rc
        from groundstation.view import replay_window as rw
        from groundstation.view.replay_items import read_parts
        from groundstation.view.rerun_sink import RerunView, ViewConfig

        factor = parse_speed(speed)
        try:
            bounds = (rw.parse_bound(start) if start else None, rw.parse_bound(end) if end else None)
            rw.check_order(*bounds)
            parts = rp.plan(expand(files))  # every file's header read: a missing or non-MCAP one stops us here
        except ViewError as e:  # a bad bound, a reversed window, files of two recordings: bad usage
            raise UsageError(str(e)) from None
        if parts.missing:
            typer.echo(f"warning: part(s) {', '.join(map(str, parts.missing))} of {one_line(parts.name)} not given; "
                       "the timeline has a hole there", err=True)
        chosen = default_viewer(viewer, rrd)
        web_port, grpc_port = viewer_ports(chosen, web_port, grpc_port)
        config = ViewConfig(viewer=chosen, rrd=rrd, web_port=web_port, grpc_port=grpc_port, replay=True)
        statuses = [RecordingContents() for _ in parts.files]
        tally = rw.Tally()
        items = rw.select(read_parts(parts, statuses), *bounds, tally)
        shown = parts.files[0].name if len(parts.files) == 1 else f"{parts.name} ({len(parts.files)} parts)"
        began = time.perf_counter()
        partial = rrd if rrd is not None and not rrd.exists() else None  # removed again if nothing is shown
        with _removed_on_error(partial), RerunView.open(config, name=parts.files[0].stem
                                                         if len(parts.files) == 1 else parts.name) as view:
            say_where(view)  # now: the browser loads the viewer while the recording is read, and gets it in slices
            if factor is None:
                with Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.completed} frames"),
                              TimeElapsedColumn(), transient=True, disable=not sys.stderr.isatty()) as progress:
                    task = progress.add_task(f"reading {in_markup(shown)}", total=None)
                    if bounds == (None, None):  # the whole recording: SAMPLEs in columns
                        # in slices: the viewer opens on the first minutes while the rest is converted
                        batch, count = rc.convert_parts(
                            parts, statuses, lambda done: progress.update(task, completed=done),  # type: ignore[arg-type]
                            sink=view.send)
                    else:
                        batch, count = rc.convert(_progress_items(items, progress, task))
                view.send(batch)
            else:
                count = rp.play(items, view.feed_model, factor)
            if bounds != (None, None):
                tally.check_window(start, end)
            rp.check_nonempty(count, parts.files[0] if len(parts.files) == 1 else shown, statuses[0])
            for path, status in zip(parts.files, statuses, strict=True):
                if status.truncated:
                    typer.echo(f"warning: {one_line(path)} was cut short (no footer); showing what was complete",
                               err=True)
                if status.damaged_chunks:
                    typer.echo(f"warning: {one_line(path)}: {status.damaged_chunks} damaged chunk(s) skipped",
                               err=True)
            if rrd is not None:
                view.flush()
                typer.echo(f"wrote {one_line(rrd)}: {count} frames in {time.perf_counter() - began:.2f} s")
            elif chosen == Viewer.NONE:  # read through and shown nowhere: say so, or it looks like nothing happened
                typer.echo(f"read {count} frames of {one_line(shown)} in {time.perf_counter() - began:.2f} s; "
                           "--viewer none shows them nowhere (add --rrd FILE to keep them, or --viewer web)")
            if view.address:
                if factor is None:
                    view.flush()
                    typer.echo(f"sent {count} frames to the viewer in {time.perf_counter() - began:.2f} s", err=True)
                wait_for_interrupt("serving the web viewer")
                stopped = True
    if stopped:
        raise typer.Exit(130)  # ended by Ctrl-C, after a clean shutdown: the one convention (README)


def view(
    url: Annotated[str | None, typer.Argument(
        help="The agent: tcp://, serial://, sim://, hub://RUN (default: $DIVE_URL, else the running `dive run`).")]
    = None,
    viewer: ViewerOption = None,
    rrd: Annotated[Path | None, typer.Option("--rrd", help="Also save the stream to this .rrd file.")] = None,
    web_port: WebPortOption = 9090,
    grpc_port: GrpcPortOption = 9876,
    key_file: KeyFileOption = None,
    foxglove: FoxgloveOption = None,
) -> None:
    """Watch the agent live in the Rerun view without commanding it, or in Foxglove with its controls.

    With --foxglove, Foxglove shows the parameters and controls; Rerun then opens only with --viewer or --rrd."""
    signal.signal(signal.SIGTERM, _interrupt)
    stopped = False
    with _one_line_errors():
        from groundstation.cli.common import wait_while_run_connects
        from groundstation.links import make_link
        from groundstation.links.runs import attach_url

        if foxglove is not None:
            wait_while_run_connects(url)  # as `dive record` does: a run still connecting is waited for
            _view_in_foxglove(attach_url(url), foxglove, viewer, rrd, web_port, grpc_port, key_file)
            return
        from groundstation.cli.common import err
        from groundstation.cli.waiting import BusyLine
        from groundstation.session.agent_session import Session, SessionConfig
        from groundstation.view.rerun_sink import RerunView, ViewConfig

        wait_while_run_connects(url)  # after the imports (a second or so): attached as soon as the run is up
        link = make_link(attach_url(url))
        chosen = default_viewer(viewer, rrd)
        web_port, grpc_port = viewer_ports(chosen, web_port, grpc_port)
        config = ViewConfig(viewer=chosen, rrd=rrd, web_port=web_port, grpc_port=grpc_port)
        with RerunView.open(config, name=link.url) as live:
            say_where(live)
            # Signed too: a signing agent refuses an unsigned HELLO's follow-ups (PARAM_LIST) as UNAUTHORIZED. Through
            # a run's hub, the run backfills for every tool: no LOG_REQUESTs of our own.
            session_config = SessionConfig(key=resolve_key(key_file), backfill=not link.url.startswith("hub://"))
            with BusyLine(err) as busy, Session(link, session_config, listeners=[live, busy]) as session:
                hello = session.agent_hello
                if link.url.startswith("hub://"):
                    from protocol import messages as m

                    # the run's episode table, last dumps and recent telemetry first (run/history.py): the
                    # learning curve and the heatmaps are whole from the start
                    session.command(m.LogRequest(first_sample=0, end_sample=0xFFFFFFFF))
                typer.echo(f"watching {one_line(hello.name) if hello else 'the agent'} at {one_line(link.url)}")
                ended = wait_for_interrupt("watching", session)
            if ended and live.address:  # what it showed stays to be looked at, as a run's own web viewer does
                wait_for_interrupt(f"the web viewer stays at {live.address}")
            stopped = not ended or bool(live.address)
    if stopped:
        raise typer.Exit(130)  # ended by Ctrl-C, after a clean shutdown: the one convention (README)


def _view_in_foxglove(url: str, port: int, viewer: Viewer | None, rrd: Path | None, web_port: int, grpc_port: int,
                      key_file: Path | None) -> None:
    """`dive view --foxglove`: the server bound first, then attached to the agent (a run's hub by default); the
    Rerun view too, on the same session, when --viewer or --rrd asks for it. Until Ctrl-C or SIGTERM."""
    from contextlib import AbstractContextManager, nullcontext

    rerun = viewer is not None or rrd is not None
    if rerun:
        chosen = default_viewer(viewer, rrd)
        web_port, grpc_port = viewer_ports(chosen, web_port, grpc_port)
    fox = open_foxglove(port, name=f"dive view {url}")
    with closing_foxglove(fox):
        session = fox.attach(url, resolve_key(key_file))
        opened: AbstractContextManager[RerunView | None] = nullcontext()
        if rerun:  # Rerun (a second or so to import) only when asked for
            from groundstation.view.rerun_sink import RerunView, ViewConfig

            opened = RerunView.open(ViewConfig(viewer=chosen, rrd=rrd, web_port=web_port, grpc_port=grpc_port),
                                    name=session.link.url)
        with opened as live:
            if live is not None:
                say_where(live)
                session.add_listener(live)
            if session.link.url.startswith("hub://"):
                from protocol import messages as m

                # the run's episode table, last dumps and recent telemetry (run/history.py), kept for Foxglove's
                # late clients as for the Rerun view: the learning curve and the heatmaps whole from the start
                session.command(m.LogRequest(first_sample=0, end_sample=0xFFFFFFFF))
            hello = session.agent_hello
            typer.echo(f"serving {one_line(hello.name) if hello else 'the agent'} at {one_line(session.link.url)} "
                       f"to Foxglove on {fox.address}")
            if wait_for_interrupt("serving Foxglove", session):
                return  # the run ended: exit 0
    raise typer.Exit(130)  # ended by Ctrl-C, after a clean shutdown: the one convention (README)
