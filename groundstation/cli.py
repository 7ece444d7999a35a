"""The `dive` command line: parses, calls library code, and maps errors to one line and an exit code."""

from __future__ import annotations

import functools
import json
import os
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from enum import StrEnum
from pathlib import Path
from typing import Annotated, Any, TypeVar
from urllib.parse import urlencode

import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.text import Text

from groundstation import view_cli
from groundstation.errors import GroundStationError
from groundstation.keys import KEY_FILE_ENV, KeyFileOption, keygen, resolve_key
from groundstation.links import default_url, make_link
from groundstation.recorder import RecorderConfig
from groundstation.rerun_view import Viewer
from groundstation.runner import RunConfig, RunStatus, add_marker, load_params_file, run
from groundstation.safe_files import replaced_atomically, unused_name
from groundstation.safe_output import SafeConsole, in_markup, one_line, printable, styled
from groundstation.session import Session, SessionConfig
from groundstation.signals import stop_on_signals
from groundstation.simulator_process import run_simulator_command
from protocol import DumpKind, Mode
from protocol import messages as m

app = typer.Typer(
    name="dive",
    help="Ground station for the micro diving agent: connect, command, record (MCAP), view (Rerun), replay.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
)
log_app = typer.Typer(help="Inspect, export and repair recordings.", no_args_is_help=True)
app.add_typer(log_app, name="log")

_FORWARD = {"allow_extra_args": True, "ignore_unknown_options": True, "help_option_names": []}
F = TypeVar("F", bound=Callable[..., Any])
err = SafeConsole(stderr=True)  # agent text and file names are data: no markup, control characters escaped
out = SafeConsole()


def _one_line_errors(func: F) -> F:
    """Our errors (and a bad file) become one line on stderr and exit code 1; Ctrl-C exits 130."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (GroundStationError, OSError) as e:
            message = str(e).replace("\n", " ") or type(e).__name__
            err.print(Text.assemble(("dive:", "bold red"), " ", one_line(message)), soft_wrap=True)
            raise typer.Exit(1) from None
        except KeyboardInterrupt:
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


@contextmanager
def _session(url: str | None, key_file: Path | None = None) -> Iterator[Session]:
    session = Session(make_link(url), SessionConfig(reconnect=False, backfill=False, key=resolve_key(key_file)))
    with session:
        yield session


_URL_HELP = "tcp://HOST:PORT, serial:///dev/ttyUSB0?baud=115200, sim://?speed=max (default: $DIVE_URL or sim://)"
UrlArg = Annotated[str | None, typer.Argument(help=_URL_HELP, show_default=False)]


# ---------------------------------------------------------------------- the main job
@app.command("run")
@_one_line_errors
def run_command(
    url: UrlArg = None,
    episodes: Annotated[int, typer.Option(help="stop after this many episodes (0 = until Ctrl-C)")] = 0,
    speed: Annotated[str | None, typer.Option(help="built-in virtual agent only: time factor or 'max'")] = None,
    seed: Annotated[int | None, typer.Option(help="built-in virtual agent only: random seed")] = None,
    preset: Annotated[str | None, typer.Option(
        help="built-in virtual agent only: plant preset, paper (default) or hardware")] = None,
    learner: Annotated[str | None, typer.Option(
        help="built-in virtual agent only: learner, paper (default), actuator3, rmax or literal")] = None,
    viewer: view_cli.ViewerOption = None,
    rrd: Annotated[Path | None, typer.Option(help="also save the live Rerun stream to this .rrd file")] = None,
    web_port: view_cli.WebPortOption = 9090,
    target_depth: Annotated[float | None, typer.Option(help="target depth z_d [m]")] = None,
    z_tol: Annotated[float | None, typer.Option(help="half-height of the learning region [m]")] = None,
    zdot_tol: Annotated[float | None, typer.Option(help="velocity bound of the learning region [m/s]")] = None,
    success_time: Annotated[float | None, typer.Option(help="time in the region that counts as success [s]")] = None,
    param: Annotated[list[str] | None, typer.Option(help="NAME=VALUE, any agent parameter (repeatable)")] = None,
    params: Annotated[Path | None, typer.Option(help="file of parameters: JSON or `name = value` lines")] = None,
    out_path: Annotated[Path | None, typer.Option("--out", help="recording directory, or a .mcap file name")] = None,
    split_mb: Annotated[float, typer.Option(help="start a new file after this many MB (0 = never)")] = 0.0,
    split_minutes: Annotated[float, typer.Option(help="start a new file after this many minutes (0 = never)")] = 0.0,
    reconnect: Annotated[bool, typer.Option(help="reconnect after a link loss and backfill the gap")] = True,
    key_file: KeyFileOption = None,
) -> None:
    """Connect, set parameters, start learning and record everything to MCAP until N episodes or Ctrl-C."""
    url = _with_sim_options(url, speed=speed, seed=seed, preset=preset, learner=learner)
    values: dict[str, str] = load_params_file(params) if params else {}
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
    config = RunConfig(url=url, episodes=episodes, params=values, recorder=recorder,
                       session=SessionConfig(reconnect=reconnect, key=resolve_key(key_file)))
    view = view_cli.open_live_view(viewer, rrd, web_port, name=url, headless_default=Viewer.NONE)
    columns = (SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
               TimeElapsedColumn())
    stop, signalled = threading.Event(), list[str]()
    with stop_on_signals(stop, signalled), view_cli.closing_view(view), \
            Progress(*columns, console=err, transient=False) as bar:
        task = bar.add_task(f"connecting to {in_markup(url)}", total=episodes or None)
        shown = 0

        def show(status: RunStatus) -> None:
            nonlocal shown
            for line in status.messages[shown:]:
                bar.console.print(styled(line, "yellow"))
            shown = len(status.messages)
            bar.update(task, completed=status.episodes, description=_describe(status))

        result = run(config, show, stop=stop, listeners=[view] if view is not None else [])
        for path in result.paths:  # before a served web viewer waits: the path is printed however the run ends
            typer.echo(printable(path))
    if result.paths:
        err.print(f"next: dive log info {result.paths[-1]}\n      dive replay {result.paths[-1]}"
                  + ("" if view is not None else "\n      (dive run --viewer web shows the run live in a browser)"),
                  style="dim")
    if result.interrupted or signalled:
        err.print(f"stopped by {signalled[0] if signalled else 'Ctrl-C'}; the recording is complete", style="dim")
    if result.lost:
        err.print(f"{result.lost} samples lost: the agent's log no longer held them", style="yellow")
    if result.still_missing - result.lost:
        err.print(f"{result.still_missing - result.lost} samples not backfilled though the agent's log still "
                  "holds them (the link did not bring them in time)", style="yellow")


def _describe(s: RunStatus) -> str:
    link = s.link
    last = f"{s.last_duration_s:.1f} s {s.last_reason}" if s.last_duration_s is not None else "-"
    rtt = link.get("rtt_median_ms")
    quality = (f"loss {100 * link.get('loss_fraction', 0.0):.1f}%"
               + (f" rtt {rtt:.1f} ms" if rtt is not None else "")) if link else "link -"
    state = "" if s.link_up else " [red]link down[/]"
    return f"episodes: {s.successes} ok / {s.failures} failed, last {last}, {quality}{state}"


def _with_sim_options(url: str | None, **sim_options: object) -> str:
    """Add the built-in agent's options (`--speed`, `--seed`, ...) to a sim:// URL as query parameters."""
    url = url or default_url()
    options = {k: str(v) for k, v in sim_options.items() if v is not None}
    if not options:
        return url
    if not url.startswith("sim://"):
        flags = ", ".join(f"--{k}" for k in options)
        raise typer.BadParameter(f"{flags} apply to the built-in virtual agent (sim://) only")
    return url + ("&" if "?" in url else "?") + urlencode(options)


# ---------------------------------------------------------------------- commanding
@app.command()
@_one_line_errors
def status(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Show the agent's identity, mode, battery, on-board log and link quality."""
    with _session(url, key_file) as s:
        deadline = time.monotonic() + 2.5
        while s.last_heartbeat is None and time.monotonic() < deadline:
            time.sleep(0.05)
        hello, hb = s.agent_hello, s.last_heartbeat
        assert hello is not None
        out.print(f"agent {one_line(repr(hello.name))} id {hello.node_id:08x} firmware "
                  f"{hello.firmware_major}.{hello.firmware_minor}.{hello.firmware_patch} boot {hello.boot_id:08x}")
        if hb is not None:
            mode = Mode(hb.mode).name if hb.mode in Mode._value2member_map_ else str(hb.mode)
            out.print(f"mode {mode}, battery {hb.battery_mv / 1000:.2f} V, uptime {hb.uptime_ms / 1000:.0f} s, "
                      f"episode {hb.episode}, log samples [{hb.log_first_sample}, {hb.log_next_sample})")
        snap = s.stats.snapshot(s.decoder.stats)
        rtt = snap["rtt_median_ms"]
        out.print(f"{len(s.params)} parameters; link: {snap['rx_frames']} frames, {snap['rx_lost']} lost, "
                  f"{snap['rx_rejects']} rejected" + (f", rtt {rtt:.1f} ms" if rtt is not None else ""))


class ParamAction(StrEnum):
    get = "get"
    set = "set"


@app.command("params")
@_one_line_errors
def params_command(
    url: Annotated[str, typer.Argument(help="the agent's URL")],
    action: Annotated[ParamAction | None, typer.Argument(help="get NAME | set NAME VALUE")] = None,
    name: Annotated[str | None, typer.Argument(show_default=False)] = None,
    value: Annotated[str | None, typer.Argument(show_default=False)] = None,
    key_file: KeyFileOption = None,
) -> None:
    """List the agent's parameters, or get / set one."""
    with _session(url, key_file) as s:
        if action is None:
            for p in s.params:
                name_shown = one_line(p.name)
                out.print(f"{p.index:3d} {name_shown:24s} {p.display_value:>12s}   [{p.minimum:g} .. {p.maximum:g}]")
            return
        if name is None:
            raise typer.BadParameter("give a parameter NAME", param_hint="NAME")
        if action == ParamAction.get:
            p = s.get_param(name)
        else:
            if value is None:
                raise typer.BadParameter("give a VALUE to set", param_hint="VALUE")
            p = s.set_param(name, value)
        out.print(f"{p.name} = {p.display_value}")


@app.command()
@_one_line_errors
def surface(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Emergency surface: maximum volume now, in any mode."""
    with _session(url, key_file) as s:
        s.command(m.Surface())
    out.print("surfacing")


@app.command()
@_one_line_errors
def hover(url: Annotated[str, typer.Argument(help="the agent's URL")],
          depth: Annotated[float, typer.Argument(help="depth to hold [m]")], key_file: KeyFileOption = None) -> None:
    """Hold a depth with the recovery controller (no learning)."""
    with _session(url, key_file) as s:
        s.command(m.Hover(depth_m=depth))
    out.print(f"hovering at {depth:g} m")


class DumpChoice(StrEnum):
    values = "values"
    policy = "policy"
    q = "q"
    counts = "counts"


_DUMP_KINDS = {DumpChoice.values: DumpKind.VALUES, DumpChoice.policy: DumpKind.POLICY,
               DumpChoice.q: DumpKind.Q_VALUES, DumpChoice.counts: DumpKind.COUNTS}


@app.command()
@_one_line_errors
def dump(url: UrlArg = None, kind: Annotated[DumpChoice, typer.Option(help="what to dump")] = DumpChoice.values,
         key_file: KeyFileOption = None) -> None:
    """Fetch the value function, policy, Q values or model counts and print them as JSON."""
    with _session(url, key_file) as s:
        snapshot = s.dump(_DUMP_KINDS[kind], timeout_s=10.0)
    out.print_json(json.dumps(snapshot.as_dict()))


@app.command()
@_one_line_errors
def mark(text: Annotated[str, typer.Argument(help="what happened (recorded on /marker by a running `dive run`)")]
         ) -> None:
    """Put a marker into the recording of the `dive run` running on this machine."""
    add_marker(text)


VIRTUAL_LOW_BATTERY_V = 3.0  # the low_batt_v minimum: below the simulated battery's empty voltage (3.4 V)


def _name_values(items: list[str]) -> Iterator[tuple[str, float]]:
    for item in items:
        name, sep, raw = item.partition("=")
        try:
            yield name.strip(), float(raw)
        except ValueError:
            sep = ""
        if not sep:
            raise typer.BadParameter(f"expected NAME=NUMBER, got {item!r}", param_hint="--param")


@app.command("check")
@_one_line_errors
def check_command(
    url: UrlArg = None,
    key_file: Annotated[Path | None, typer.Option(
        help="the agent's signing key: runs the signing checks (default: $DIVE_KEY_FILE)")] = None,
    allow_motion: Annotated[bool, typer.Option(
        help="run the checks that move the agent or change its learned model (always on for sim://)")] = False,
    only: Annotated[list[str] | None, typer.Option(help="run only these checks or groups, e.g. junk, ack.echo")] = None,
    param: Annotated[list[str] | None, typer.Option(
        help="NAME=VALUE set for the run and put back after it (repeatable)")] = None,
    timeout: Annotated[float, typer.Option(help="seconds to wait for an ACK or a reply")] = 2.0,
    mode_timeout: Annotated[float, typer.Option(help="seconds to wait for a mode change (surfacing, recovery)")]
    = 60.0,
    as_json: Annotated[bool, typer.Option("--json", help="machine-readable report")] = False,
    sentences: Annotated[bool, typer.Option(help="quote the tested spec sentence for every check, not only failures")]
    = False,
) -> None:
    """Conformance suite: drive the agent over its link and report, per SPEC.md section, what passes and fails."""
    from groundstation.check import CheckOptions, Timeouts, run_checks, selected
    from groundstation.check.report import print_report

    if timeout <= 0 or mode_timeout <= 0:
        raise typer.BadParameter("timeouts must be positive", param_hint="--timeout/--mode-timeout")
    checks = selected(tuple(only or ()))
    if not checks:
        raise typer.BadParameter(f"no check matches {', '.join(only or ())}", param_hint="--only")
    url = url or default_url()
    key = resolve_key(key_file)
    if key_file is None and os.environ.get(KEY_FILE_ENV):
        key_file = Path(os.environ[KEY_FILE_ENV])
    values = dict(_name_values(param or []))
    if url.startswith("sim://"):  # a virtual agent started for this run: nothing real moves, no time to lose
        allow_motion = True
        # At full speed hours of agent time pass in seconds: its simulated 2 h battery would run flat mid-run.
        values.setdefault("low_batt_v", VIRTUAL_LOW_BATTERY_V)
        extra = {k: v for k, v in (("speed", "max"), ("key_file", key_file and str(key_file)))
                 if v and f"{k}=" not in url}
        url = url + ("&" if "?" in url else "?") + urlencode(extra) if extra else url
    options = CheckOptions(url=url, key=key, allow_motion=allow_motion, only=tuple(only or ()),
                           params=tuple(values.items()),
                           timeouts=Timeouts(reply_s=timeout, heartbeat_s=max(3.0, timeout), mode_s=mode_timeout))
    with Progress(SpinnerColumn(), TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                  TimeElapsedColumn(), console=err, transient=True, disable=as_json) as bar:
        task = bar.add_task(f"checking {in_markup(url)}", total=len(checks))
        report = run_checks(options, lambda o: bar.update(task, advance=1, description=o.check.id))
    if as_json:
        out.print_json(json.dumps(report.as_dict()))
    else:
        print_report(report, out, sentences)
    raise typer.Exit(0 if report.passed else 1)


# ---------------------------------------------------------------------- recordings
def _existing(path: Path) -> Path:
    if not path.is_file():
        raise GroundStationError(f"no such recording: {path}")
    return path


@log_app.command("info")
@_one_line_errors
def log_info(file: Path, as_json: Annotated[bool, typer.Option("--json", help="machine-readable")] = False) -> None:
    """Sessions, duration, episodes with outcome and length, samples, loss, backfill and missing samples."""
    from groundstation.loginfo import format_summary, summarize

    summary = summarize(_existing(file))
    if as_json:
        out.print_json(json.dumps(summary.as_dict()))
    else:
        out.print(format_summary(summary))


class ExportFormat(StrEnum):
    csv = "csv"
    npz = "npz"
    minari = "minari"


@log_app.command("export")
@_one_line_errors
def log_export(file: Path, format: Annotated[ExportFormat, typer.Option(
                   help="csv: samples; npz: offline-RL transitions; minari: a Minari dataset (FILE may be a folder)")]
               = ExportFormat.csv,
               out_path: Annotated[Path | None, typer.Option(
                   "--out", help="output file; for minari the datasets folder (default: Minari's own)")] = None,
               ) -> None:
    """Export samples as CSV, (s, a, r, s', terminated, truncated) transitions as .npz, or a Minari dataset."""
    from groundstation.export import export_csv, export_npz

    if format == ExportFormat.minari:
        _export_minari(file, out_path)
        return
    target = out_path or _existing(file).with_suffix(f".{format.value}")
    with replaced_atomically(target, source=_existing(file)) as temporary:
        rows = (export_csv if format == ExportFormat.csv else export_npz)(file, temporary)
    out.print(f"{target} ({rows} rows)")


def _export_minari(file: Path, root: Path | None) -> None:
    from groundstation.minari_export import dataset_id_for, export_minari
    from groundstation.recording import open_recording

    if not file.exists():
        raise GroundStationError(f"no such recording: {file}")
    result = export_minari(open_recording(file), dataset_id_for(file), root)
    left = f", {result.left_out} left out (holes or no end)" if result.left_out else ""
    out.print(f"Minari dataset {result.dataset_id} in {result.root}: {result.episodes} episodes, "
              f"{result.steps} steps{left}", markup=False, soft_wrap=True)
    root_hint = f"MINARI_DATASETS_PATH={result.root} " if root is not None else ""
    out.print(f"load it: {root_hint}python -c \"import minari; minari.load_dataset('{result.dataset_id}')\"",
              markup=False, soft_wrap=True)


@log_app.command("recover")
@_one_line_errors
def log_recover(file: Path, out_path: Annotated[Path | None, typer.Option("--out", help="output file")] = None
                ) -> None:
    """Rewrite a truncated recording (after a crash or kill) into a finished, indexed one."""
    from groundstation.mcap_io import recover

    target = out_path or unused_name(_existing(file).with_name(file.stem + "-recovered.mcap"))
    with replaced_atomically(target, source=_existing(file)) as temporary:
        count, truncated = recover(file, temporary)
    note = "was truncated" if truncated else "was already complete"
    out.print(f"{target} ({count} messages; the original {note})")


# ---------------------------------------------------------------------- the simulator process
@app.command(context_settings=_FORWARD, add_help_option=False)
def sim(ctx: typer.Context) -> None:
    """Serve a virtual diving agent over TCP or a pseudo-terminal (`dive sim --help` for options)."""
    raise typer.Exit(run_simulator_command(["sim", *ctx.args]))


@app.command(context_settings=_FORWARD, add_help_option=False)
def study(ctx: typer.Context) -> None:
    """Run N trials x E episodes of a learner on the simulated plant (`dive study --help` for options)."""
    raise typer.Exit(run_simulator_command(["study", *ctx.args]))


app.command(name="view")(view_cli.view)
app.command(name="replay")(view_cli.replay)
app.command(name="keygen")(keygen)


def main() -> None:
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)


if __name__ == "__main__":
    main()
