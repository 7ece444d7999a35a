"""`dive check`: the conformance suite against an agent, a pass/fail line per SPEC.md check."""

from __future__ import annotations

import json
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated
from urllib.parse import urlencode

import typer

from groundstation.cli.common import UrlArg, err, one_line_errors, out
from groundstation.safe_output import in_markup
from groundstation.session.keys import KEY_FILE_ENV, resolve_key

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


@one_line_errors
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
        help="seconds to wait for an ACK or a reply \\[default: 2; sim://: 10, its first use of a learner compiles]")]
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
    from groundstation.cli.waiting import busy_text
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
        report = run_checks(options, lambda o: bar.update(task, advance=1, description=o.check.id),
                            lambda reason: bar.update(task, description=in_markup(busy_text(reason))))
    if as_json:
        out.print_json(json.dumps(report.as_dict()))
    else:
        print_report(report, out, sentences)
    raise typer.Exit(0 if report.passed else 1)
