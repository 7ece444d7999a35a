"""The operator's controls: start, stop, pause, resume, target, reset-model, surface and hover, each answered with
the agent's ACK and the mode it ends in, a refusal with why and what to do instead."""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import TYPE_CHECKING, Annotated

import typer

from groundstation.cli.common import UrlArg, agent_session, one_line_errors, out, split_url
from groundstation.cli.validate import UsageError
from groundstation.errors import CommandError, CommandMayHaveRun, GroundStationError
from groundstation.session.keys import KeyFileOption

if TYPE_CHECKING:
    from groundstation.session.agent_session import Session
    from protocol import Message

HOVER_RANGE_M = (0.0, 2.5)  # SPEC: CMD_HOVER; the agent refuses other depths too
TARGET_RANGE_M = (0.05, 2.5)  # SPEC section 13: target_depth_m
MODE_WAIT_S = 3.0  # the agent's next HEARTBEAT (1 Hz of agent time) says the mode the command left it in

# What to do instead, by (command, the agent's mode) for a NOT_ALLOWED_IN_MODE (SPEC.md section 6's matrix).
_LEARNING_NOW = "it is learning: pause first (dive pause holds the depth) or surface first: dive surface"
_SURFACING_NOW = "it is surfacing: wait for IDLE (dive status), then try again"
HINTS: dict[tuple[str, str], str] = {
    ("CMD_START", "LEARNING"): "it is learning already",
    ("CMD_START", "RECOVERING"): "it is learning already (recovering to a start)",
    ("CMD_START", "SURFACING"): _SURFACING_NOW,
    ("CMD_PAUSE", "IDLE"): "it is not learning: dive start starts learning",
    ("CMD_PAUSE", "HOVER"): "it is hovering, not learning: dive start learns from here, dive stop surfaces",
    ("CMD_PAUSE", "PAUSED"): "it is paused already: dive resume continues learning",
    ("CMD_PAUSE", "SURFACING"): _SURFACING_NOW,
    ("CMD_HOVER", "LEARNING"): _LEARNING_NOW,
    ("CMD_HOVER", "RECOVERING"): _LEARNING_NOW,
    ("CMD_HOVER", "SURFACING"): _SURFACING_NOW,
    ("CMD_SET_TARGET", "LEARNING"): "it is learning: dive pause, then dive target DEPTH, then dive resume",
    ("CMD_RESET_MODEL", "LEARNING"): "it is learning: pause or stop first: dive pause, or dive stop",
    ("PARAM_SET", "LEARNING"): "pause first: dive pause, set it, then dive resume",
    ("PARAM_SET", "RECOVERING"): "stop first: dive stop (or dive pause), set it, then dive start",
    ("PARAM_SET", "PAUSED"): "stop first: dive stop, set it, then dive start",
}


def mode_name(s: Session) -> str:
    """The agent's mode from its latest HEARTBEAT ("unknown" before the first)."""
    from protocol import Mode

    beat = s.last_heartbeat
    if beat is None:
        return "unknown"
    return Mode(beat.mode).name if beat.mode in Mode._value2member_map_ else f"mode {beat.mode}"


def refused(name: str, error: CommandError, mode: str, what: str = "") -> GroundStationError:
    """A NACK as one line: the agent's reason, its mode and what to do ("surface first: dive surface")."""
    from protocol import AckResult

    if error.result != AckResult.NOT_ALLOWED_IN_MODE:
        return error
    hint = HINTS.get((name, mode), "")
    subject = f"{name} {what}".strip()
    return GroundStationError(f"{subject} refused: not allowed while the agent is {mode}"
                              + (f"; {hint}" if hint else ""))


def known_mode(s: Session) -> str:
    """The agent's mode, waiting for its first HEARTBEAT if a tool that just attached has none yet."""
    return wait_for_mode(s) if s.last_heartbeat is None else mode_name(s)


def wait_for_mode(s: Session, timeout_s: float = MODE_WAIT_S) -> str:
    """The mode in the first HEARTBEAT after now (the latest one known if none comes in time)."""
    before = s.last_heartbeat
    deadline = time.monotonic() + timeout_s
    while s.last_heartbeat is before and time.monotonic() < deadline:
        time.sleep(0.02)
    return mode_name(s)


def send_control(s: Session, message: Message) -> str:
    """Send one control command; the line that answers it: the ACK and the mode the agent is in after it."""
    name = message.DEFINITION.name
    try:
        ack = s.command(message)
    except CommandMayHaveRun as e:  # not a refusal: the first try may have run (SPEC.md s. 5); the mode tells
        return f"{e} ({s.link.url})"
    except CommandError as e:
        raise refused(name, e, known_mode(s)) from None
    reason = f" ({ack.reason})" if ack.reason else ""
    return f"{name} accepted{reason} ({s.link.url}): the agent is {wait_for_mode(s)}"


def _run(url: str | None, key_file: Path | None, message: Message, then: str = "") -> None:
    with agent_session(url, key_file, reconnect=True) as s:
        out.print(send_control(s, message) + then, soft_wrap=True, highlight=False)


def _depth(args: list[str], usage: str, bounds: tuple[float, float], what: str) -> tuple[str | None, float]:
    url, words = split_url(args)
    if len(words) != 1:
        raise UsageError(f"expected `{usage}`")
    try:
        depth = float(words[0])
    except ValueError:
        raise UsageError(f"DEPTH must be a number of metres, not {words[0]!r}") from None
    if not bounds[0] <= depth <= bounds[1]:  # the agent refuses it too
        raise GroundStationError(f"{what} {depth:g} m is outside [{bounds[0]:g}, {bounds[1]:g}] m")
    return url, depth


@one_line_errors
def start(url: UrlArg = None,
          episodes: Annotated[int, typer.Option(min=0, max=2**32 - 1,
                                                help="episodes of this start (0 = the max_episodes parameter)")] = 0,
          key_file: KeyFileOption = None) -> None:
    """Start learning (from IDLE, HOVER or PAUSED); hands the agent back to a `dive run` an operator took it from."""
    from protocol import messages as m

    _run(url, key_file, m.StartLearning(max_episodes=episodes))


@one_line_errors
def stop(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Stop learning or hovering (the episode is aborted) and surface; `dive start` starts again."""
    from protocol import messages as m

    _run(url, key_file, m.Stop(), "; dive start starts learning again")


@one_line_errors
def pause(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Pause learning: the episode is aborted and the agent holds its depth; `dive resume` continues."""
    from protocol import messages as m

    _run(url, key_file, m.Pause(), "; dive resume continues")


@one_line_errors
def resume(url: UrlArg = None, key_file: KeyFileOption = None) -> None:
    """Continue learning after `dive pause` (CMD_START from PAUSED)."""
    from protocol import messages as m

    with agent_session(url, key_file, reconnect=True) as s:
        mode = known_mode(s)
        if mode != "PAUSED":
            raise GroundStationError(f"the agent is {mode}, not paused: dive start starts learning")
        out.print(send_control(s, m.StartLearning(max_episodes=0)), soft_wrap=True, highlight=False)


@one_line_errors
def target(args: Annotated[list[str], typer.Argument(
               help="the new target depth of learning \\[m], after the agent's URL", metavar="[URL] DEPTH",
               show_default=False)],
           key_file: KeyFileOption = None) -> None:
    """Set the target depth learning holds (not while LEARNING: pause first)."""
    from protocol import messages as m

    url, depth = _depth(args, "dive target [URL] DEPTH", TARGET_RANGE_M, "target depth")
    _run(url, key_file, m.SetTarget(target_depth_m=depth))


@one_line_errors
def reset_model(url: UrlArg = None,
                yes: Annotated[bool, typer.Option("--yes", help="do not ask (needed when not on a terminal)")]
                = False,
                key_file: KeyFileOption = None) -> None:
    """Forget what the agent learned: model, values, policy, episode count and successes."""
    from protocol import messages as m

    confirm_reset("CMD_RESET_MODEL forgets everything the agent learned", yes)
    _run(url, key_file, m.ResetModel())


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
    from protocol import messages as m

    with agent_session(url, key_file, reconnect=True) as s:
        s.command(m.Surface())
        out.print(f"surfacing ({s.link.url}): the agent is {wait_for_mode(s)}; dive start starts learning again",
                  soft_wrap=True, highlight=False)


@one_line_errors
def hover(args: Annotated[list[str], typer.Argument(
              help="the depth to hold \\[m], after the agent's URL (as for params)", metavar="[URL] DEPTH",
              show_default=False)],
          key_file: KeyFileOption = None) -> None:
    """Hold a depth with the recovery controller (no learning; from IDLE, HOVER or PAUSED)."""
    from protocol import messages as m

    url, depth = _depth(args, "dive hover [URL] DEPTH", HOVER_RANGE_M, "hover depth")
    with agent_session(url, key_file, reconnect=True) as s:
        try:
            s.command(m.Hover(depth_m=depth))
        except CommandMayHaveRun as e:
            out.print(f"{e} ({s.link.url})", soft_wrap=True, highlight=False)
            return
        except CommandError as e:
            raise refused("CMD_HOVER", e, known_mode(s)) from None
        out.print(f"hovering at {depth:g} m ({s.link.url}): the agent is {wait_for_mode(s)}; dive start starts "
                  "learning again", soft_wrap=True, highlight=False)
