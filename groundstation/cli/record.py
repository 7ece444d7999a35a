"""`dive record [URL]`: a recorder that commands nothing; through a running `dive run`'s hub, a second recording.

The agent has one link and the run holds it; `dive record` attaches to the run's hub (hub://, the default when no
URL is given) and writes every frame the hub fans out into an MCAP file of its own, in the format `dive run`
writes: the same SAMPLEs, nothing taken from the agent's link. It sets no parameter and starts nothing, so it
can be started and stopped at any time (a second copy on another disk, a recording with other split sizes).
"""

from __future__ import annotations

import signal
import time
from pathlib import Path
from typing import Annotated

import typer

from groundstation.cli.common import wait_while_run_connects
from groundstation.cli.validate import UsageError
from groundstation.errors import GroundStationError, RecordingExistsError
from groundstation.safe_output import one_line, printable
from groundstation.session.keys import KeyFileOption, resolve_key


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def _fail(message: str, code: int = 1) -> typer.Exit:
    typer.echo(f"dive: {one_line(message)}", err=True)  # the prefix of every dive error (cli.py)
    return typer.Exit(code)


def record(
    url: Annotated[str | None, typer.Argument(
        help="hub://RUN, or an agent no run is connected to: tcp://, serial:// (default: $DIVE_URL, else the "
             "running `dive run`)", show_default=False)] = None,
    out_path: Annotated[Path | None, typer.Option("--out", help="recording directory, or a .mcap file name")] = None,
    split_mb: Annotated[float, typer.Option(min=0, help="start a new file after this many MB on disk (0 = never)")]
    = 0.0,
    split_minutes: Annotated[float, typer.Option(
        min=0, help="start a new file after this many minutes (0 = never)")] = 0.0,
    key_file: KeyFileOption = None,
) -> None:
    """Record the agent's telemetry to MCAP without commanding it (a second recorder beside a `dive run`)."""
    signal.signal(signal.SIGTERM, _interrupt)  # a service manager's stop is a Ctrl-C: a complete recording
    paths: list[Path] = []
    interrupted = False
    try:
        from groundstation.cli.common import err
        from groundstation.cli.waiting import BusyLine
        from groundstation.links import make_link
        from groundstation.links.runs import attach_url, hub_address
        from groundstation.recording.recorder import Recorder, RecorderConfig
        from groundstation.recording.run_end import RunEndAware
        from groundstation.run.job import session_info
        from groundstation.session.agent_session import Session, SessionConfig

        directory = out_path.parent if out_path is not None and out_path.suffix == ".mcap" else \
            out_path or Path("recordings")
        config = RecorderConfig(directory, out_path if out_path is not None and out_path.suffix == ".mcap" else None,
                                int(split_mb * 1e6), split_minutes * 60.0)
        if config.first_file is not None and config.first_file.exists():  # before attaching, as dive run does
            raise RecordingExistsError(f"{one_line(config.first_file)} exists; a recording is never overwritten: "
                                       "give another name or a directory")
        wait_while_run_connects(url)
        link = make_link(attach_url(url))
        through_hub = link.url.startswith("hub://")
        recorder = Recorder(config, session_info(link.url))
        # Through a hub the run backfills for every tool (its replayed frames are fanned out) and its end ends ours:
        # no LOG_REQUESTs of our own, no reconnecting to a run that is gone, and no link loss recorded for its end.
        session_config = SessionConfig(key=resolve_key(key_file), backfill=not through_hub, reconnect=not through_hub)
        busy = BusyLine(err)  # an agent still starting answers BUSY: one line says we wait
        listener = RunEndAware(recorder, hub_address(link.url)[0].run) if through_hub else recorder
        session = Session(link, session_config, listeners=[listener, busy])
        try:
            hello = session.connect()
            recorder.set_parameters(session.params.values())
            typer.echo(f"recording {one_line(hello.name)} at {one_line(link.url)}; Ctrl-C to stop", err=True)
            try:
                while recorder.failure is None and session.failure is None and (session.link_up or not through_hub):
                    time.sleep(0.2)
            except KeyboardInterrupt:
                interrupted = True
        finally:
            session.close()
            recorder.close()
            paths = recorder.paths
        for path in paths:
            typer.echo(printable(path))
        if recorder.failure is not None:
            raise recorder.failure
        if session.failure is not None:
            raise session.failure
        if not interrupted:
            typer.echo("the run ended; the recording is complete", err=True)
    except UsageError as e:
        raise _fail(str(e), 2) from None
    except GroundStationError as e:
        raise _fail(str(e)) from None
    except KeyboardInterrupt:
        interrupted = True
    if interrupted:
        raise typer.Exit(130)  # stopped by Ctrl-C, the recording complete: the one convention (README)
