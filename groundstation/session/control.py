"""The operator's controls (`dive start`, ..., Foxglove's services): each one's ACK and the mode the agent ends in."""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from groundstation.errors import CommandError, CommandMayHaveRun, GroundStationError
from protocol import AckResult, Mode, messages

if TYPE_CHECKING:
    from groundstation.session.agent_session import Session
    from protocol import Message

HOVER_RANGE_M = (0.0, 2.5)  # SPEC: CMD_HOVER; the agent refuses other depths too
TARGET_RANGE_M = (0.05, 2.5)  # SPEC section 13: target_depth_m
MODE_WAIT_S = 3.0  # the agent's next HEARTBEAT (1 Hz of agent time) says the mode the command left it in
NOT_SENT = "NOT_SENT"  # an Answer's result when the ground refused before sending (resume of an agent not paused)
MAY_HAVE_RUN = "MAY_HAVE_RUN"  # a retry across a reconnect refused in a way that shows the first try may have run

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
    # SPEC s. 13: a learner parameter is refused in LEARNING and RECOVERING, never in PAUSED: pausing is enough
    ("PARAM_SET", "RECOVERING"): "pause first: dive pause, set it, then dive resume",
}


@dataclass(frozen=True, slots=True)
class Answer:
    """The agent's answer to one control: its ACK (result and reason), the mode after it, and the line to show."""

    command: str
    result: str  # AckResult's name, or NOT_SENT
    reason: str
    mode: str
    line: str

    @property
    def accepted(self) -> bool:
        return self.result == AckResult.ACCEPTED.name

    @property
    def refused(self) -> bool:
        """Refused for sure: neither accepted nor possibly run (SPEC.md s. 5: the mode in the line tells which)."""
        return not self.accepted and self.result != MAY_HAVE_RUN

    def as_dict(self) -> dict[str, Any]:
        return {"command": self.command, "accepted": self.accepted, "result": self.result, "reason": self.reason,
                "mode": self.mode, "message": self.line}

    def raise_if_refused(self) -> Answer:
        """The answer, or its line as an error (the CLI's exit 1) when the command was refused."""
        if self.refused:
            raise GroundStationError(self.line)
        return self


def mode_name(s: Session) -> str:
    """The agent's mode from its latest HEARTBEAT ("unknown" before the first)."""
    beat = s.last_heartbeat
    if beat is None:
        return "unknown"
    return Mode(beat.mode).name if beat.mode in Mode._value2member_map_ else f"mode {beat.mode}"


def refused(name: str, error: CommandError, mode: str, what: str = "") -> GroundStationError:
    """A NACK as one line: the agent's reason, its mode and what to do ("surface first: dive surface")."""
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


def _result_name(result: int | None) -> str:
    return AckResult(result).name if result is not None and result in AckResult._value2member_map_ else \
        f"result {result}"


def control(s: Session, message: Message, then: str = "", accepted_line: str = "", hints: bool = True) -> Answer:
    """Send one control command. A NACK is an Answer too (its line says why and what to do, or with `hints` off
    the agent's own words and reason); no ACK at all (CommandTimeout, LinkError) raises. `accepted_line` replaces
    the standard line ("{mode}" is the mode)."""
    name = message.DEFINITION.name
    try:
        ack = s.command(message)
    except CommandMayHaveRun as e:  # not a refusal: the first try may have run (SPEC.md s. 5); the mode tells
        return Answer(name, MAY_HAVE_RUN, "", e.mode, f"{e} ({s.link.url})")
    except CommandError as e:
        if e.result is None:
            raise  # no ACK came: nothing to answer with
        mode = known_mode(s)
        return Answer(name, _result_name(e.result), "", mode, str(refused(name, e, mode) if hints else e))
    mode = wait_for_mode(s)
    reason = f" ({ack.reason})" if ack.reason else ""
    line = accepted_line.replace("{mode}", mode) if accepted_line else \
        f"{name} accepted{reason} ({s.link.url}): the agent is {mode}"
    return Answer(name, AckResult.ACCEPTED.name, ack.reason, mode, line + then)


def check_depth(depth: float, bounds: tuple[float, float], what: str) -> float:
    """A depth the agent would accept, or one line saying the range (before anything is sent)."""
    if not bounds[0] <= depth <= bounds[1]:
        raise GroundStationError(f"{what} {depth:g} m is outside [{bounds[0]:g}, {bounds[1]:g}] m")
    return depth


# ---------------------------------------------------------------------- the controls, one function each
def start(s: Session, episodes: int = 0) -> Answer:
    return control(s, messages.StartLearning(max_episodes=episodes))


def stop(s: Session) -> Answer:
    return control(s, messages.Stop(), "; dive start starts learning again")


def pause(s: Session) -> Answer:
    return control(s, messages.Pause(), "; dive resume continues")


def resume(s: Session) -> Answer:
    """CMD_START from PAUSED only: from any other mode it would start learning, which is not what resume says."""
    mode = known_mode(s)
    if mode != "PAUSED":
        return Answer("CMD_START", NOT_SENT, "", mode, f"the agent is {mode}, not paused: dive start starts learning")
    return control(s, messages.StartLearning(max_episodes=0))


def target(s: Session, depth_m: float) -> Answer:
    check_depth(depth_m, TARGET_RANGE_M, "target depth")
    return control(s, messages.SetTarget(target_depth_m=depth_m))


def reset_model(s: Session) -> Answer:
    return control(s, messages.ResetModel())


def surface(s: Session) -> Answer:
    """Emergency surface: accepted in every mode (a NACK here is an error, not a hint)."""
    answer = control(s, messages.Surface(), accepted_line=f"surfacing ({s.link.url}): the agent is " "{mode}; "
                     "dive start starts learning again", hints=False)  # no hint helps: say what the agent said
    return answer.raise_if_refused()


def hover(s: Session, depth_m: float) -> Answer:
    check_depth(depth_m, HOVER_RANGE_M, "hover depth")
    return control(s, messages.Hover(depth_m=depth_m), accepted_line=f"hovering at {depth_m:g} m ({s.link.url}): "
                   "the agent is {mode}; dive start starts learning again")
