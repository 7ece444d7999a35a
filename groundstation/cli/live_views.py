"""The live views `dive run` and `dive view` share: which Rerun viewer and ports, the Foxglove server bound before
any agent starts, where each is announced, and how long each stays up (until Ctrl-C, or the watched run's end)."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import typer

from groundstation.cli.validate import UsageError, free_port, port_problem
from groundstation.safe_output import one_line
from groundstation.view.options import Viewer

if TYPE_CHECKING:  # Rerun and foxglove are imported by the commands that open them
    from groundstation.session.agent_session import Session
    from groundstation.view.foxglove.live import FoxgloveLive
    from groundstation.view.rerun_sink import RerunView


DEFAULT_PORTS = {"--web-port": 9090, "--grpc-port": 9876}


def viewer_ports(viewer: Viewer, web_port: int, grpc_port: int) -> tuple[int, int]:
    """The ports a served web viewer uses, on a machine that can keep it to its owner (else UsageError, exit 2).
    Both must be free, else the address printed would show another process's data. A default port in use (a second
    viewer beside `dive run --viewer web`) moves to a free one; a port given that is in use fails, every such port
    named in one line."""
    if viewer != Viewer.WEB:
        return web_port, grpc_port
    from groundstation.view.web_server import private_network_problem, private_refusal

    reason = private_network_problem()
    if reason is not None:  # served anyway, every local user could read the run: refused before anything starts
        raise UsageError(private_refusal(reason))
    chosen, problems = [], []
    for option, port in (("--web-port", web_port), ("--grpc-port", grpc_port)):
        problem = port_problem(port, option)
        if problem and port == DEFAULT_PORTS[option]:
            port = free_port()
            typer.echo(f"the default {option} {DEFAULT_PORTS[option]} is in use: using {port}", err=True)
        elif problem:
            problems.append(problem)
        chosen.append(port)
    if problems:
        raise UsageError("; ".join(problems))
    return chosen[0], chosen[1]


def default_viewer(viewer: Viewer | None, rrd: Path | None, headless_default: Viewer = Viewer.WEB) -> Viewer:
    """The viewer asked for; else none when only --rrd is given, else spawn with a display, else the given one."""
    if viewer is not None:
        return viewer
    if rrd is not None:
        return Viewer.NONE
    return Viewer.SPAWN if os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY") else headless_default


def say_where(view: RerunView, err: bool = False) -> None:
    """The web viewer's address, and one line when the viewer's port answers more than its owner."""
    if view.address:
        typer.echo(f"Rerun web viewer: {view.address}", err=err)
    if view.notice:
        typer.secho(f"note: {view.notice}", err=True, fg="yellow")


def open_live_view(viewer: Viewer | None, rrd: Path | None, web_port: int, name: str,
                   headless_default: Viewer = Viewer.WEB, grpc_port: int = 9876) -> RerunView | None:
    """The live view `dive run` attaches to its session, or None when neither a viewer nor a file is wanted."""
    chosen = default_viewer(viewer, rrd, headless_default)
    if chosen == Viewer.NONE and rrd is None:
        return None
    web_port, grpc_port = viewer_ports(chosen, web_port, grpc_port)
    from groundstation.view.rerun_sink import ViewConfig, attach_view

    live = attach_view(ViewConfig(viewer=chosen, rrd=rrd, web_port=web_port, grpc_port=grpc_port), name=name)
    if live is not None:
        say_where(live, err=True)
    return live


@contextmanager
def closing_view(live: RerunView | None, signalled: list[str] | None = None,
                 closed: Callable[[], None] | None = None) -> Iterator[None]:
    """Close the live view however the run ends; a served web viewer stays up until Ctrl-C first, unless the run
    was ended by a signal (`signalled`: SIGTERM from a service manager means stop now, with one signal). `closed`
    is called once the viewer is down (the run's announcement as finished is withdrawn then)."""
    try:
        yield
    finally:
        try:
            if live is not None:
                if live.address and not signalled:
                    wait_for_interrupt(f"the run is over; the web viewer stays at {live.address}")
                live.close()
        finally:
            if closed is not None:
                closed()


LIVE_LAYOUT = "docs/foxglove/live-layout.json"


def open_foxglove(port: int, name: str) -> FoxgloveLive:
    """The Foxglove server, bound now (before any agent is started): a port in use, the default one too, is one line
    and exit 2. The default one is not moved to a free port: another user who took 8765 first would then be the
    server the operator's app connects to (issue 38 N5). The printed name's #tag is this server's alone: the
    Foxglove app shows the server's name, so the operator can tell theirs from an impostor."""
    from groundstation.view.foxglove.live import FoxgloveLive, FoxglovePortError

    try:
        live = FoxgloveLive(port, name)
    except FoxglovePortError as e:
        raise UsageError(str(e)) from None
    typer.echo(f"Foxglove: {live.address} (Foxglove app: Open connection, Foxglove WebSocket, this URL; layout: "
               f"{LIVE_LAYOUT}); server name ends #{live.fingerprint}; your user only", err=True)
    return live


@contextmanager
def closing_foxglove(live: FoxgloveLive | None) -> Iterator[None]:
    """Close the server however the run ends; what its door and publisher refused or dropped, in one line."""
    try:
        yield
    finally:
        if live is not None:
            live.close()
            said = live.refusals()
            if said:
                typer.echo(f"Foxglove: {said}", err=True)


def wait_for_interrupt(what: str, session: Session | None = None) -> bool:
    """Keep going (serving the web viewer, watching the agent) until Ctrl-C or SIGTERM, then return.

    With the session it watches through, also until that session ends by itself, rather than watch nothing for ever:
    what it gave up on (the run's hub dropped this tool for falling behind, another agent answered) is raised, one
    line and exit 1; the run it is attached to through its hub has ended: one line, and True is returned."""
    from groundstation.links.runs import is_running

    typer.echo(f"{what}; Ctrl-C to stop", err=True)
    url = session.link.url if session is not None else ""
    run = url.removeprefix("hub://") if url.startswith("hub://") else None
    try:
        while True:
            time.sleep(0.2)
            if session is None:
                continue
            if session.failure is not None:
                raise session.failure
            if run is not None and not session.link_up and not is_running(run):
                typer.echo(f"dive run {one_line(run)} ended and closed its hub")
                return True
    except KeyboardInterrupt:
        pass
    return False
