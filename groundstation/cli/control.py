"""The operator's controls: start, stop, pause, resume, target, reset-model, surface and hover, each answered with
the agent's ACK and the mode it ends in, a refusal with why and what to do instead (the logic: session/control.py)."""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from groundstation.cli.common import UrlArg, agent_session, one_line_errors, out, split_url
from groundstation.cli.validate import UsageError
from groundstation.errors import GroundStationError
from groundstation.session import control
from groundstation.session.control import HOVER_RANGE_M, TARGET_RANGE_M, check_depth
from groundstation.session.keys import KeyFileOption

if TYPE_CHECKING:
    from groundstation.session.agent_session import Session
    from groundstation.session.control import Answer


def _run(url: str | None, key_file: Path | None, act: Callable[[Session], Answer], fetch_params: bool = True) -> None:
    with agent_session(url, key_file, reconnect=True, fetch_params=fetch_params) as s:
        out.print(act(s).raise_if_refused().line, soft_wrap=True, highlight=False)


def _depth(args: list[str], usage: str, bounds: tuple[float, float], what: str) -> tuple[str | None, float]:
    url, words = split_url(args)
    if len(words) != 1:
        raise UsageError(f"expected `{usage}`")
    try:
        depth = float(words[0])
    except ValueError:
        raise UsageError(f"DEPTH must be a number of metres, not {words[0]!r}") from None
    return url, check_depth(depth, bounds, what)  # before connecting: nothing is sent


@one_line_errors
def start(url: UrlArg = None,
          episodes: Annotated[int, typer.Option(min=0, max=2**32 - 1,
                                                help="episodes of this start (0 = the max_episodes parameter)")] = 0,
          key_file: KeyFileOption = None) -> None:
    """Start learning (from IDLE, HOVER or PAUSED); hands the agent back to a `dive run` an operator took it from."""
    _run(url, key_file, lambda s: control.start(s, episodes))


@one_line_errors
def stop(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Stop learning or hovering (the episode is aborted) and surface; `dive start` starts again."""
    _run(url, key_file, control.stop)


@one_line_errors
def pause(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Pause learning: the episode is aborted and the agent holds its depth; `dive resume` continues."""
    _run(url, key_file, control.pause)


@one_line_errors
def resume(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Continue learning after `dive pause` (CMD_START from PAUSED)."""
    _run(url, key_file, control.resume)


@one_line_errors
def target(args: Annotated[list[str], typer.Argument(
               help="the new target depth of learning \\[m], after the agent's URL", metavar="[URL] DEPTH",
               show_default=False)],
           key_file: KeyFileOption = None) -> None:
    """Set the target depth learning holds (not while LEARNING: pause first)."""
    url, depth = _depth(args, "dive target [URL] DEPTH", TARGET_RANGE_M, "target depth")
    _run(url, key_file, lambda s: control.target(s, depth))


@one_line_errors
def reset_model(url: UrlArg = None,
                yes: Annotated[bool, typer.Option("--yes", help="do not ask (needed when not on a terminal)")]
                = False,
                key_file: KeyFileOption = None) -> None:
    """Forget what the agent learned: model, values, policy, episode count and successes."""
    confirm_reset("CMD_RESET_MODEL forgets everything the agent learned", yes)
    _run(url, key_file, control.reset_model)


def confirm_reset(what: str, yes: bool, flag: str = "--yes") -> None:
    """Ask on a terminal; elsewhere (a script, CI) only --yes (or --reset-model) goes ahead."""
    if yes:
        return
    if not sys.stdin.isatty():
        raise UsageError(f"{what}: add {flag} to go ahead (not on a terminal, so nobody can confirm)")
    if not typer.confirm(f"{what}. Go ahead?", default=False):
        raise GroundStationError("nothing changed")


@one_line_errors
def surface(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Emergency surface: maximum volume now, in any mode."""
    # no PARAM_LIST first: a keyed agent refuses it unsigned, and runs an unsigned CMD_SURFACE on purpose (SPEC 1.2):
    # the one command that must work without the key did not (issue 38 N9)
    _run(url, key_file, control.surface, fetch_params=False)


@one_line_errors
def hover(args: Annotated[list[str], typer.Argument(
              help="the depth to hold \\[m], after the agent's URL (as for params)", metavar="[URL] DEPTH",
              show_default=False)],
          key_file: KeyFileOption = None) -> None:
    """Hold a depth with the recovery controller (no learning; from IDLE, HOVER or PAUSED)."""
    url, depth = _depth(args, "dive hover [URL] DEPTH", HOVER_RANGE_M, "hover depth")
    _run(url, key_file, lambda s: control.hover(s, depth))
