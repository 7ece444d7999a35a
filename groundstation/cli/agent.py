"""The commands that talk to an agent: status, params, dump, and mark (to the running run); controls: control.py."""

from __future__ import annotations

import json
import os
import time
from enum import StrEnum
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from groundstation.cli.common import UrlArg, agent_session, one_line_errors, out, split_url, tool_name
from groundstation.cli.validate import UsageError
from groundstation.errors import GroundStationError
from groundstation.safe_output import one_line
from groundstation.session.keys import KeyFileOption

if TYPE_CHECKING:
    from groundstation.session.agent_session import Session
    from groundstation.session.dumps import Dump
    from groundstation.session.params import Parameter


@one_line_errors
def status(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Show the agent's identity, mode, battery, on-board log and link quality."""
    from groundstation.cli.status_episodes import StatusEpisodes
    from groundstation.session.status_line import AgentStatus, status_line

    idle = _runs_not_up(url)
    if idle:
        for line in idle:
            out.print(one_line(line), soft_wrap=True, highlight=False)
        return
    with agent_session(url, key_file) as s:
        agent = AgentStatus()
        history = StatusEpisodes(agent)
        s.add_listener(s.rx_listener(history.received))
        start = time.monotonic()
        if s.link.url.startswith("hub://"):
            history.ask(s)
        # a heartbeat comes every second; a SAMPLE (the depth) in IDLE too, but a quiet agent is not waited for long
        while (s.last_heartbeat is None and time.monotonic() < start + 2.5) or \
                (agent.depth_m is None and time.monotonic() < start + 1.2):
            time.sleep(0.05)
        history.wait(start + 3.0)
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
        if agent.mode is None and hb is not None:
            agent.update(hb)  # the heartbeat came before the listener
        if agent.target_m is None and "target_depth_m" in s.params:
            agent.param("target_depth_m", s.params.get("target_depth_m").value)  # no EPISODE_START seen yet
        if history.last_end is not None:
            out.print(history.last_end_text(), highlight=False)
        out.print(f"status: {status_line(agent, snap, s.link_up, _run_alarm(s.link.url))}", soft_wrap=True,
                  highlight=False)


def _runs_not_up(url: str | None) -> list[str]:
    """With no agent named: what the runs announced on this machine are doing when none has a hub to attach to
    (one still connecting, one over whose web viewer is still up); empty when there is one to ask, or none."""
    if url or os.environ.get("DIVE_URL"):
        return []
    from groundstation.links.runs import running

    announced = running()
    return [] if any(info.state == "running" for info in announced) else [info.state_line() for info in announced]


def _run_alarm(url: str) -> str:
    """Through a run's hub: the run's alarm flag, as its status line shows it (the run announces it)."""
    if not url.startswith("hub://"):
        return ""  # an agent asked directly has no run watching it: no alarms are kept
    from groundstation.links.runs import NoRunError, hub_address

    try:
        return hub_address(url)[0].alarm
    except NoRunError:
        return ""  # the run ended while we asked


_PARAM_ACTIONS = ("get", "set", "save", "diff", "load")


@one_line_errors
def params_command(
    args: Annotated[list[str] | None, typer.Argument(
        help="get NAME (or a pattern: 'z_*'), set NAME VALUE, save FILE, diff FILE (exit 1 if it differs) or load "
             "FILE (none: list them all), after the "
             "agent's URL (default: $DIVE_URL, else the running `dive run`)",
        metavar="[URL] [ACTION ...]", show_default=False)] = None,
    reset_model: Annotated[bool, typer.Option(
        "--reset-model", help="go ahead when a set or load restarts the learner (it forgets what it learned); "
                              "on a terminal you are asked instead")] = False,
    key_file: KeyFileOption = None,
) -> None:
    """List, get or set the agent's parameters, or save, compare with or load a TOML file of them.

    The list shows each one's value, unit, range, what it is and whether a change resets learning.

    A set or load sends only the values that differ from the agent's."""
    from groundstation.session.paramfile import read_params, write_params

    url, words = split_url(list(args or []), _PARAM_ACTIONS)
    action, rest = (words[0], words[1:]) if words else (None, [])
    wanted = {"get": 1, "set": 2, "save": 1, "diff": 1, "load": 1}
    if action is not None and action not in wanted:
        raise UsageError(f"unknown params action {action!r}: use get NAME, set NAME VALUE, save/diff/load FILE")
    if action is not None and len(rest) != wanted[action]:
        shape = {"get": "get NAME", "set": "set NAME VALUE"}.get(action, f"{action} FILE")
        raise UsageError(f"expected `dive params [URL] {shape}`")
    from_file = read_params(Path(rest[0])) if action in ("diff", "load") else {}
    with agent_session(url, key_file) as s:
        if action is None:
            from groundstation.session.param_plan import describe

            for p in s.params:
                out.print(one_line(describe(p)), soft_wrap=True, highlight=False)
        elif action == "get":
            for p in _matching(s, rest[0]):
                out.print(f"{p.name} = {p.display_value}", highlight=False)
        elif action == "set":
            _set_all(s, {rest[0]: rest[1]}, reset_model)
        elif action == "save":
            write_params(Path(rest[0]), s.params)
            out.print(f"{rest[0]}: {len(s.params)} parameters")
        elif action == "diff":
            from groundstation.session.param_plan import plan

            change = plan(s.params, from_file)
            for p, _ in change.changes:
                out.print(f"{p.name}: agent {p.display_value}, file {from_file[p.name]}")
            out.print(f"{len(change.changes)} of {len(from_file)} differ"
                      + (f"; loading it: {change.restart_warning()}" if change.restarts else ""))
            if change.changes:
                raise typer.Exit(1)  # as diff(1): 0 the same, 1 different, so a script can tell
        else:
            _set_all(s, from_file, reset_model)


def _matching(s: Session, pattern: str) -> list[Parameter]:
    """The parameters a name or a shell pattern (`z_*`, `*_s`) names; a name unknown says the names it is near."""
    if not any(c in pattern for c in "*?["):
        return [s.get_param(pattern)]
    import fnmatch

    found = [p for p in s.params if fnmatch.fnmatchcase(p.name, pattern)]
    if not found:
        raise GroundStationError(f"no parameter matches {pattern!r} (dive params lists them all)")
    return found


def _set_all(s: Session, values: dict[str, str], reset_model: bool) -> None:
    """Set what differs from the agent's values, after every check: names, values, the agent's mode, and a
    confirmed learner restart. Nothing is sent when one check fails."""
    from groundstation.cli.control import confirm_reset
    from groundstation.session.param_plan import apply, checked_plan

    change = checked_plan(s, values)
    warning = change.restart_warning()
    if warning:
        confirm_reset(warning, reset_model, "--reset-model")
    if len(change.unchanged) == 1:
        p = change.unchanged[0]
        out.print(f"{p.name} = {p.display_value} (unchanged, not sent)")
    elif change.unchanged:  # a load of a whole file: one line, not one per parameter
        out.print(f"{len(change.unchanged)} of {len(values)} unchanged, not sent")
    apply(s, change, lambda done: out.print(f"{done.name} = {done.display_value}"))


class DumpChoice(StrEnum):
    values = "values"
    policy = "policy"
    q = "q"
    counts = "counts"


_DUMP_KINDS = {DumpChoice.values: "VALUES", DumpChoice.policy: "POLICY", DumpChoice.q: "Q_VALUES",
               DumpChoice.counts: "COUNTS"}  # DumpKind names (protocol is imported by the command)
_GRID_PARAMS = ("target_depth_m", "z_tol_m", "zdot_tol_mps", "z_cells", "zdot_cells")  # what --png draws over


@one_line_errors
def dump(url: UrlArg = None, kind: Annotated[DumpChoice, typer.Option(help="what to dump")] = DumpChoice.values,
         png: Annotated[Path | None, typer.Option(
             help="draw the values or the policy over the learner's grid into this PNG instead of printing JSON")]
         = None,
         key_file: KeyFileOption = None) -> None:
    """Fetch the value function, policy, Q values or model counts and print them as JSON (or draw one: --png)."""
    if png is not None:
        from groundstation.recording.safe_files import check_output

        if kind not in (DumpChoice.values, DumpChoice.policy):
            raise UsageError(f"--png draws --kind values or policy; {kind.value} is printed as JSON")
        check_output(png)  # before asking the agent: a recording is never overwritten
    with agent_session(url, key_file) as s:
        from protocol import DumpKind

        snapshot = s.dump(DumpKind[_DUMP_KINDS[kind]], timeout_s=10.0)
        grid_params = {name: s.params.get(name).value for name in _GRID_PARAMS} if png is not None else {}
    if png is None:
        out.print_json(json.dumps(snapshot.as_dict()))
    else:
        _draw_dump(png, snapshot, grid_params)


def _draw_dump(png: Path, snapshot: Dump, grid_params: dict[str, float]) -> None:
    import numpy as np

    from groundstation.recording.safe_files import replaced_atomically
    from groundstation.view.dump_plot import write_dump_png
    from groundstation.view.heatmap import dump_grid

    values = np.asarray(snapshot.values())
    p = grid_params
    grid = dump_grid(len(values), p["target_depth_m"], p["z_tol_m"], p["zdot_tol_mps"], int(p["z_cells"]),
                     int(p["zdot_cells"]))
    if grid is None:
        raise GroundStationError(f"the {snapshot.kind.name} dump holds {len(values)} states: not one row of the grid")
    with replaced_atomically(png) as temporary:
        write_dump_png(temporary, snapshot.kind, values, grid, snapshot.episode)
    out.print(f"{one_line(png)}: {snapshot.kind.name.lower()} of episode {snapshot.episode} over {grid.z_cells} x "
              f"{grid.zdot_cells} cells" + (f" x {grid.blocks} actuator bins" if grid.blocks > 1 else ""),
              soft_wrap=True)  # one line a script can read the path from


@one_line_errors
def mark(text: Annotated[str, typer.Argument(help="what happened (recorded on /marker by the run)")],
         run: Annotated[str | None, typer.Option(help="the run (hub://RUN's RUN) when several are running")] = None,
         ) -> None:
    """Put a marker into the recording of the `dive run` running on this machine (the one named with --run)."""
    from groundstation.links.runs import find_run
    from groundstation.run.marker import send_marker

    try:
        text.encode()
    except UnicodeEncodeError:  # bytes from argv that are no UTF-8 (a shell's $'\xff'): surrogates Python kept
        raise UsageError("the marker's text is not UTF-8: write it as text") from None
    info = find_run(run.removeprefix("hub://") if run else None)
    send_marker(info, text, tool=tool_name())
    where = f" ({info.recording})" if info.recording else ""
    out.print(f"marked in run {info.run}{where}")


@one_line_errors
def ack(run: Annotated[str | None, typer.Option(help="the run (hub://RUN's RUN) when several are running")] = None,
        ) -> None:
    """Acknowledge the alarms of the `dive run` running on this machine: its status line's alarm flag goes (an
    alarm still active shows as acked until it clears). The key `a` in the run's pane does the same."""
    from groundstation.links.runs import find_run
    from groundstation.run.marker import send_ack

    info = find_run(run.removeprefix("hub://") if run else None)
    out.print(send_ack(info, tool=tool_name()), soft_wrap=True, highlight=False)
