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
from typing import TYPE_CHECKING, Annotated, Any, TypeVar
from urllib.parse import urlencode

import typer
from rich.text import Text

from groundstation import record_cli, view_cli
from groundstation.errors import GroundStationError
from groundstation.keys import KEY_FILE_ENV, KeyFileOption, keygen, resolve_key
from groundstation.safe_files import replaced_atomically, unused_name
from groundstation.safe_output import SafeConsole, in_markup, one_line, printable
from groundstation.signals import stop_on_signals
from groundstation.simulator_process import run_simulator_command
from groundstation.validate import UsageError, parse_speed
from groundstation.view_options import Viewer

if TYPE_CHECKING:  # the session, recorder and runner (mcap, numpy) are imported by the commands that use them
    from groundstation.session import Session

app = typer.Typer(
    name="dive",
    help="Ground station for the micro diving agent: connect, command, record (MCAP), view (Rerun), replay.\n\n"
         "Exit codes: 0 done, 1 failed (one line on stderr says why), 2 bad usage, 130 stopped by Ctrl-C.",
    no_args_is_help=True,
    pretty_exceptions_enable=False,
    rich_markup_mode="rich",
    context_settings={"help_option_names": ["-h", "--help"]},
)
def _version(value: bool) -> None:
    if value:
        from groundstation.hello import tool_version

        typer.echo(f"dive {tool_version()}")
        raise typer.Exit()


@app.callback()
def _options(version: Annotated[bool, typer.Option("--version", callback=_version, is_eager=True,
                                                   help="Print dive's version and exit.")] = False) -> None:
    """Options of dive itself (the app's help text is the Typer's)."""


log_app = typer.Typer(help="Inspect, export and repair recordings.", no_args_is_help=True,
                      context_settings={"help_option_names": ["-h", "--help"]})
app.add_typer(log_app, name="log")

_FORWARD = {"allow_extra_args": True, "ignore_unknown_options": True, "help_option_names": []}
F = TypeVar("F", bound=Callable[..., Any])
err = SafeConsole(stderr=True)  # agent text and file names are data: no markup, control characters escaped
out = SafeConsole()


def _one_line_errors(func: F) -> F:
    """Our errors (and a bad file) become one line on stderr and exit code 1 (a bad value: 2); Ctrl-C exits 130."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except UsageError as e:
            err.print(Text.assemble(("dive:", "bold red"), " ", one_line(str(e))), soft_wrap=True)
            raise typer.Exit(2) from None
        except (GroundStationError, OSError) as e:
            message = str(e).replace("\n", " ") or type(e).__name__
            err.print(Text.assemble(("dive:", "bold red"), " ", one_line(message)), soft_wrap=True)
            raise typer.Exit(1) from None
        except KeyboardInterrupt:
            raise typer.Exit(130) from None

    return wrapper  # type: ignore[return-value]


@contextmanager
def _session(url: str | None, key_file: Path | None = None) -> Iterator[Session]:
    """A session with *the* agent: the URL given, else $DIVE_URL, else the running `dive run` (never a new sim)."""
    from groundstation.links import make_link
    from groundstation.runs import attach_url
    from groundstation.session import Session, SessionConfig

    session = Session(make_link(attach_url(url)),
                      SessionConfig(reconnect=False, backfill=False, key=resolve_key(key_file)))
    with session:
        yield session


_URL_HELP = ("tcp://HOST:PORT, serial:///dev/ttyUSB0?baud=115200, sim://?speed=max, hub://RUN "
             "(default: $DIVE_URL, else the running `dive run`)")
UrlArg = Annotated[str | None, typer.Argument(help=_URL_HELP, show_default=False)]


# ---------------------------------------------------------------------- the main job
@app.command("run")
@_one_line_errors
def run_command(
    url: UrlArg = None,
    episodes: Annotated[int, typer.Option(min=0, max=2**32 - 1,
                                          help="stop after this many episodes (0 = until Ctrl-C)")] = 0,
    speed: Annotated[str | None, typer.Option(help="built-in virtual agent only: time factor or 'max'")] = None,
    seed: Annotated[int | None, typer.Option(min=0, max=2**32 - 1,
                                             help="built-in virtual agent only: random seed")] = None,
    preset: Annotated[str | None, typer.Option(
        help="built-in virtual agent only: plant preset, paper (default) or hardware")] = None,
    learner: Annotated[str | None, typer.Option(
        help="built-in virtual agent only: learner, paper (default), actuator3, rmax or literal")] = None,
    viewer: view_cli.ViewerOption = None,
    rrd: Annotated[Path | None, typer.Option(help="also save the live Rerun stream to this .rrd file")] = None,
    web_port: view_cli.WebPortOption = 9090,
    grpc_port: view_cli.GrpcPortOption = 9876,
    target_depth: Annotated[float | None, typer.Option(help="target depth z_d \\[m]")] = None,
    z_tol: Annotated[float | None, typer.Option(help="half-height of the learning region \\[m]")] = None,
    zdot_tol: Annotated[float | None, typer.Option(help="velocity bound of the learning region \\[m/s]")] = None,
    success_time: Annotated[float | None, typer.Option(
        help="time in the region that counts as success \\[s]")] = None,
    param: Annotated[list[str] | None, typer.Option(help="NAME=VALUE, any agent parameter (repeatable)")] = None,
    params: Annotated[Path | None, typer.Option(help="file of parameters: JSON or `name = value` lines")] = None,
    out_path: Annotated[Path | None, typer.Option("--out", help="recording directory, or a .mcap file name")] = None,
    split_mb: Annotated[float, typer.Option(
        min=0, help="start a new file (NAME-part002.mcap, ...) after this many MB on disk (0 = never)")] = 0.0,
    split_minutes: Annotated[float, typer.Option(
        min=0, help="start a new file after this many minutes (0 = never)")] = 0.0,
    reconnect: Annotated[bool, typer.Option(help="reconnect after a link loss and backfill the gap")] = True,
    key_file: KeyFileOption = None,
) -> None:
    """Connect, set parameters, start learning and record everything to MCAP until N episodes or Ctrl-C."""
    from groundstation.recorder import RecorderConfig
    from groundstation.run_progress import RunDisplay
    from groundstation.runner import RunConfig, load_params_file, run
    from groundstation.session import SessionConfig

    if speed is not None:
        parse_speed(speed)  # now, not 10 s later inside the virtual agent
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
    view = view_cli.open_live_view(viewer, rrd, web_port, name=url, headless_default=Viewer.NONE,
                                   grpc_port=grpc_port)
    config = RunConfig(url=url, episodes=episodes, params=values, recorder=recorder,
                       session=SessionConfig(reconnect=reconnect, key=resolve_key(key_file)),
                       dumps_each_episode=view is not None)
    stop, signalled = threading.Event(), list[str]()
    with stop_on_signals(stop, signalled), view_cli.closing_view(view), \
            RunDisplay(err, episodes, f"connecting to {url}", virtual=url.startswith("sim://")) as display:
        result = run(config, display.show, stop=stop, listeners=[view] if view is not None else [])
        for path in result.paths:  # before a served web viewer waits: the path is printed however the run ends
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
    if result.interrupted or signalled:
        err.print(f"stopped by {signalled[0] if signalled else 'Ctrl-C'}; the recording is complete", style="dim")
        raise typer.Exit(130)  # the one convention: interrupted = 130, whatever was saved


def _with_sim_options(url: str | None, **sim_options: object) -> str:
    """Add the built-in agent's options (`--speed`, `--seed`, ...) to a sim:// URL as query parameters."""
    from groundstation.runs import run_url_default

    url = run_url_default(url)
    options = {k: str(v) for k, v in sim_options.items() if v is not None}
    if not options:
        return url
    if not url.startswith("sim://"):
        flags = ", ".join(f"--{k}" for k in options)
        raise UsageError(f"{flags} apply to the built-in virtual agent (sim://) only")
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
            from protocol import Mode

            mode = Mode(hb.mode).name if hb.mode in Mode._value2member_map_ else str(hb.mode)
            out.print(f"mode {mode}, battery {hb.battery_mv / 1000:.2f} V, uptime {hb.uptime_ms / 1000:.0f} s, "
                      f"episode {hb.episode}, log samples [{hb.log_first_sample}, {hb.log_next_sample})")
        snap = s.stats.snapshot(s.decoder.stats)
        rtt = snap["rtt_median_ms"]
        out.print(f"{len(s.params)} parameters; link: {snap['rx_frames']} frames, {snap['rx_lost']} lost, "
                  f"{snap['rx_rejects']} rejected" + (f", rtt {rtt:.1f} ms" if rtt is not None else ""))


_PARAM_ACTIONS = ("get", "set", "save", "diff", "load")
HOVER_RANGE_M = (0.0, 2.5)
_TAKES_NEGATIVE = {"ignore_unknown_options": True}  # `-5` is a value, not an unknown option


def _split_url(args: list[str], actions: tuple[str, ...] = ()) -> tuple[str | None, list[str]]:
    """An optional URL first (it has `://` or is a /dev path), then the command's own words."""
    if args and ("://" in args[0] or args[0].startswith("/dev/")) and args[0] not in actions:
        return args[0], args[1:]
    return None, args


@app.command("params", context_settings=_TAKES_NEGATIVE)
@_one_line_errors
def params_command(
    args: Annotated[list[str] | None, typer.Argument(
        help="[URL] [get NAME | set NAME VALUE | save FILE | diff FILE | load FILE]", show_default=False)] = None,
    key_file: KeyFileOption = None,
) -> None:
    """List the agent's parameters, get / set one, or save, compare with or load a TOML file of them."""
    from groundstation.paramfile import read_params, write_params

    url, words = _split_url(list(args or []), _PARAM_ACTIONS)
    action, rest = (words[0], words[1:]) if words else (None, [])
    wanted = {"get": 1, "set": 2, "save": 1, "diff": 1, "load": 1}
    if action is not None and action not in wanted:
        raise UsageError(f"unknown params action {action!r}: use get NAME, set NAME VALUE, save/diff/load FILE")
    if action is not None and len(rest) != wanted[action]:
        shape = {"get": "get NAME", "set": "set NAME VALUE"}.get(action, f"{action} FILE")
        raise UsageError(f"expected `dive params [URL] {shape}`")
    from_file = read_params(Path(rest[0])) if action in ("diff", "load") else {}
    with _session(url, key_file) as s:
        if action is None:
            for p in s.params:
                name_shown = one_line(p.name)
                out.print(f"{p.index:3d} {name_shown:24s} {p.display_value:>12s}   [{p.minimum:g} .. {p.maximum:g}]")
        elif action == "get":
            p = s.get_param(rest[0])
            out.print(f"{p.name} = {p.display_value}")
        elif action == "set":
            p = s.set_param(rest[0], rest[1])
            out.print(f"{p.name} = {p.display_value}")
        elif action == "save":
            write_params(Path(rest[0]), s.params)
            out.print(f"{rest[0]}: {len(s.params)} parameters")
        elif action == "diff":
            differ = [(n, s.params.get(n), v) for n, v in from_file.items()
                      if _param_number(s, n, str(s.params.get(n).value)) != _param_number(s, n, v)]
            for name, p, v in differ:
                out.print(f"{name}: agent {p.display_value}, file {v}")
            out.print(f"{len(differ)} of {len(from_file)} differ")
        else:
            for name in from_file:
                s.params.get(name)  # every name checked (with did-you-mean) before the first is set
            for name, value in from_file.items():
                p = s.set_param(name, value)
                out.print(f"{p.name} = {p.display_value}")


def _param_number(s: Session, name: str, text: str) -> float:
    """A value as the agent stores it (F32 parameters as f32), to compare a file's value with the agent's."""
    import struct

    from groundstation.params import ParamType, parse_value

    p = s.params.get(name)
    value = parse_value(p, text)
    return struct.unpack("<f", struct.pack("<f", value))[0] if p.param_type == ParamType.F32 else value


@app.command()
@_one_line_errors
def surface(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Emergency surface: maximum volume now, in any mode."""
    from protocol import messages as m

    with _session(url, key_file) as s:
        s.command(m.Surface())
        name = s.link.url
    out.print(f"surfacing ({name})")


@app.command(context_settings=_TAKES_NEGATIVE)
@_one_line_errors
def hover(args: Annotated[list[str], typer.Argument(help="[URL] DEPTH: the depth to hold \\[m]",
                                                    show_default=False)],
          key_file: KeyFileOption = None) -> None:
    """Hold a depth with the recovery controller (no learning)."""
    url, words = _split_url(args)
    if len(words) != 1:
        raise UsageError("expected `dive hover [URL] DEPTH`")
    try:
        depth = float(words[0])
    except ValueError:
        raise UsageError(f"DEPTH must be a number of metres, not {words[0]!r}") from None
    if not HOVER_RANGE_M[0] <= depth <= HOVER_RANGE_M[1]:  # the agent refuses it too (SPEC: CMD_HOVER)
        raise GroundStationError(f"hover depth {depth:g} m is outside [{HOVER_RANGE_M[0]:g}, {HOVER_RANGE_M[1]:g}] m")
    from protocol import messages as m

    with _session(url, key_file) as s:
        s.command(m.Hover(depth_m=depth))
        name = s.link.url
    out.print(f"hovering at {depth:g} m ({name})")


class DumpChoice(StrEnum):
    values = "values"
    policy = "policy"
    q = "q"
    counts = "counts"


_DUMP_KINDS = {DumpChoice.values: "VALUES", DumpChoice.policy: "POLICY", DumpChoice.q: "Q_VALUES",
               DumpChoice.counts: "COUNTS"}  # DumpKind names (protocol is imported by the command)


@app.command()
@_one_line_errors
def dump(url: UrlArg = None, kind: Annotated[DumpChoice, typer.Option(help="what to dump")] = DumpChoice.values,
         key_file: KeyFileOption = None) -> None:
    """Fetch the value function, policy, Q values or model counts and print them as JSON."""
    with _session(url, key_file) as s:
        from protocol import DumpKind

        snapshot = s.dump(DumpKind[_DUMP_KINDS[kind]], timeout_s=10.0)
    out.print_json(json.dumps(snapshot.as_dict()))


@app.command()
@_one_line_errors
def mark(text: Annotated[str, typer.Argument(help="what happened (recorded on /marker by the run)")],
         run: Annotated[str | None, typer.Option(help="the run (hub://RUN's RUN) when several are running")] = None,
         ) -> None:
    """Put a marker into the recording of the `dive run` running on this machine (the one named with --run)."""
    from groundstation.marker import send_marker
    from groundstation.runs import find_run

    info = find_run(run.removeprefix("hub://") if run else None)
    send_marker(info, text)
    where = f" ({info.recording})" if info.recording else ""
    out.print(f"marked in run {info.run}{where}")


REPLY_TIMEOUT_S = 2.0
SIM_REPLY_TIMEOUT_S = 10.0  # a virtual agent compiles kernels on first use: its first answer may take seconds
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
    timeout: Annotated[float | None, typer.Option(
        help="seconds to wait for an ACK or a reply [default: 2; sim://: 10, its first use of a learner compiles]")]
    = None,
    mode_timeout: Annotated[float, typer.Option(help="seconds to wait for a mode change (surfacing, recovery)")]
    = 60.0,
    as_json: Annotated[bool, typer.Option("--json", help="machine-readable report")] = False,
    sentences: Annotated[bool, typer.Option(help="quote the tested spec sentence for every check, not only failures")]
    = False,
) -> None:
    """Conformance suite: drive the agent over its link and report, per SPEC.md section, what passes and fails."""
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    from groundstation.check import CheckOptions, Timeouts, run_checks, selected
    from groundstation.check.report import print_report
    from groundstation.links import default_url

    if timeout is None:
        timeout = SIM_REPLY_TIMEOUT_S if (url or default_url()).startswith("sim://") else REPLY_TIMEOUT_S
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
        url = url + ("&" if "?" in url else "?") + urlencode(extra, safe="/") if extra else url
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
def log_info(files: Annotated[list[Path], typer.Argument(help="recordings, or folders of them")],
             as_json: Annotated[bool, typer.Option("--json", help="machine-readable")] = False) -> None:
    """Sessions, duration, episodes with outcome and length, samples, loss, backfill and missing samples."""
    from groundstation.loginfo import format_summary, summarize
    from groundstation.recording_files import being_recorded, expand, json_summary

    summaries = []
    for path in expand(files):
        summary = summarize(path)
        writer = None if summary.complete else being_recorded(path)
        summaries.append((summary, writer))
    if as_json:
        rows = [{**json_summary(s.as_dict()), "being_recorded_by": w} for s, w in summaries]
        out.print_json(json.dumps(rows[0] if len(rows) == 1 else rows))
        return
    for summary, writer in summaries:
        text = format_summary(summary)
        if writer is not None:  # no footer yet because it is still being written, not because it was cut short
            text = text.replace("  (truncated: run `dive log recover`)", f"  (being recorded by {writer})", 1)
        out.print(text)


class ExportFormat(StrEnum):
    csv = "csv"
    npz = "npz"
    minari = "minari"


@log_app.command("export")
@_one_line_errors
def log_export(files: Annotated[list[Path], typer.Argument(help="recordings, or folders of them")],
               format: Annotated[ExportFormat, typer.Option(
                   help="csv: samples; npz: offline-RL transitions; minari: a Minari dataset (FILE may be a folder)")]
               = ExportFormat.csv,
               out_path: Annotated[Path | None, typer.Option(
                   "--out", help="output file (one recording only); for minari the datasets folder "
                   "(default: Minari's own)")] = None,
               ) -> None:
    """Export samples as CSV, (s, a, r, s', terminated, truncated) transitions as .npz, or a Minari dataset.

    Several recordings (or a folder) give one output file each, beside each recording; the parts of a split
    recording given together make one (NAME.csv beside NAME-part001.mcap), episodes across parts kept whole.
    """
    from groundstation.export import export_csv, export_npz
    from groundstation.recording_files import expand, group_recordings

    if format == ExportFormat.minari:
        if len(files) != 1:
            raise UsageError("minari exports one recording or one folder at a time")
        _export_minari(files[0], out_path)
        return
    recordings = group_recordings(expand(files))
    if out_path is not None and len(recordings) > 1:
        raise UsageError(f"--out names one file, but {len(recordings)} recordings were given")
    for recording in recordings:
        first = recording.files[0]
        name = first.stem if len(recording.files) == 1 else recording.name
        target = out_path or first.with_name(f"{name}.{format.value}")
        with replaced_atomically(target, source=first) as temporary:
            rows = (export_csv if format == ExportFormat.csv else export_npz)(recording.files, temporary)
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
app.command(name="record")(record_cli.record)
app.command(name="keygen")(keygen)


def main() -> None:
    """Exit codes (README): 0 done, 1 failed, 2 bad usage, 130 interrupted. A bug is one line too, not a traceback
    (DIVE_DEBUG=1 shows it)."""
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)
    except Exception as e:  # noqa: BLE001 the last line of defence: a traceback reaching a user is a bug
        if os.environ.get("DIVE_DEBUG"):
            raise
        err.print(f"[bold red]dive: internal error:[/] {type(e).__name__}: {e} (DIVE_DEBUG=1 shows where)",
                  markup=True, soft_wrap=True, highlight=False)
        sys.exit(1)


if __name__ == "__main__":
    main()
