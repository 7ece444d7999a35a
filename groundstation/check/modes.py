"""The command x mode matrix: every command in every mode, its ACK and the mode it leaves (SPEC.md 6).

A virtual agent at full speed leaves LEARNING, RECOVERING and SURFACING on its own within milliseconds, so each
command is judged against the mode the agent was really in when it handled it: the last mode its frames showed
before the ACK. A cell is retried until the command has met the agent in the wanted mode.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from groundstation.check.agent import get_param, hover_depth, overridden, reach
from groundstation.check.errors import CheckSkipped
from groundstation.check.probe import Probe, mode_of, result_name
from groundstation.check.probe_link import Exchange
from groundstation.check.registry import check, expect
from protocol import AckResult, DumpKind, EndReason, Message, Mode
from protocol import messages as m

SECTION = "6 Modes of the agent"
TRIES = 6
# An agent far faster than real time (the C firmware behind sim:// at full speed: ~500x) may end an episode before
# the command arrives; each try at LEARNING costs one recovery.
TRIES_LEARNING = 20
ID, LE, RE, HO, PA, SU = Mode.IDLE, Mode.LEARNING, Mode.RECOVERING, Mode.HOVER, Mode.PAUSED, Mode.SURFACING
OK, NO = AckResult.ACCEPTED, AckResult.NOT_ALLOWED_IN_MODE
# What a mode becomes on its own (an episode ends, recovery settles, the surface is reached): a command that leaves
# the mode alone may be followed by these.
NATURAL: dict[Mode, frozenset[Mode]] = {
    ID: frozenset(), HO: frozenset(), PA: frozenset(), SU: frozenset({ID}),
    LE: frozenset({RE, SU}), RE: frozenset({LE, SU}),
}


@dataclass(frozen=True)
class Cell:
    result: AckResult
    after: frozenset[Mode]  # modes the first frame after the ACK may show (empty = stays)
    aborts: bool = False  # an EPISODE_END aborted follows the ACK


def _c(result: AckResult, *after: Mode, aborts: bool = False) -> Cell:
    return Cell(result, frozenset(after), aborts)


STAY = _c(OK)
REFUSED = _c(NO)
_START = _c(OK, RE, LE)  # RECOVERING, or LEARNING at once when the simulator's start_at_rest is set
_SURFACING = _c(OK, SU, ID)  # at the surface already, SURFACING may end within one step
MATRIX: dict[str, dict[Mode, Cell]] = {
    "CMD_START": {ID: _START, LE: REFUSED, RE: REFUSED, HO: _START, PA: _START, SU: REFUSED},
    "CMD_STOP": {ID: STAY, LE: _c(OK, SU, aborts=True), RE: _c(OK, SU), HO: _c(OK, SU), PA: _c(OK, SU), SU: STAY},
    "CMD_PAUSE": {ID: REFUSED, LE: _c(OK, PA, aborts=True), RE: _c(OK, PA), HO: REFUSED, PA: REFUSED, SU: REFUSED},
    "CMD_SET_TARGET": {ID: STAY, LE: REFUSED, RE: STAY, HO: STAY, PA: STAY, SU: STAY},
    "CMD_SURFACE": {ID: _SURFACING, LE: _c(OK, SU, aborts=True), RE: _c(OK, SU), HO: _c(OK, SU), PA: _c(OK, SU),
                    SU: STAY},
    "CMD_HOVER": {ID: _c(OK, HO), LE: REFUSED, RE: REFUSED, HO: _c(OK, HO), PA: _c(OK, HO), SU: REFUSED},
    "CMD_RESET_MODEL": {ID: STAY, LE: REFUSED, RE: STAY, HO: STAY, PA: STAY, SU: STAY},
}
ORDER = (ID, HO, PA, LE, RE, SU)


def _commands(probe: Probe) -> dict[str, Callable[[], Message]]:
    target = get_param(probe, "target_depth_m").value
    depth = hover_depth(probe)
    return {
        "CMD_START": lambda: m.StartLearning(max_episodes=0), "CMD_STOP": m.Stop, "CMD_PAUSE": m.Pause,
        "CMD_SET_TARGET": lambda: m.SetTarget(target_depth_m=target), "CMD_SURFACE": m.Surface,
        "CMD_HOVER": lambda: m.Hover(depth_m=depth), "CMD_RESET_MODEL": m.ResetModel,
    }


def judge_cell(probe: Probe, name: str, make: Callable[[], Message], wanted: Mode) -> tuple[Mode | None, str]:
    """Send the command once; (the mode it met, "" or what was wrong)."""
    ex = probe.command(make())
    if ex.ack is None:
        return wanted, f"{name} in {wanted.name}: no ACK"
    before = probe.mode_before(ex)
    if before is None:
        return None, ""
    cell = MATRIX[name][before]
    where = f"{name} in {before.name}"
    if ex.result != cell.result:
        return before, f"{where}: {result_name(ex.result)}, wanted {cell.result.name}"
    after = probe.mode_after(ex)
    allowed = set(cell.after or {before})
    for mode in list(allowed):
        allowed |= NATURAL[mode]
    if after not in allowed:
        shown = after.name if after is not None else "no mode shown"
        return before, f"{where}: then {shown}, wanted {'/'.join(sorted(x.name for x in allowed))}"
    if cell.aborts:
        end = probe.wait_message(m.EpisodeEnd, ex.ack_at, probe.timeouts.reply_s)
        if end is None or end[1].reason != EndReason.ABORTED:
            came = (f"the first was {_reason(end[1].reason)}" if end is not None
                    else f"none within {probe.timeouts.reply_s:g} s")
            return before, f"{where}: no EPISODE_END aborted after the ACK ({came}; {_around(probe, ex)})"
    return before, ""


def _reason(value: int) -> str:
    """An EPISODE_END's reason by name; a number SPEC.md does not define as the number."""
    return EndReason(value).name if value in EndReason._value2member_map_ else str(value)


def _around(probe: Probe, ex: Exchange) -> str:
    """What the agent sent about the command's ACK (a few frames either side): what a failed cell is judged on."""
    first = max(ex.sent_at - 4, probe.first)
    shown = []
    for index, frame in enumerate(probe.frames(first, min(ex.ack_at + 6, probe.end)), first):
        mode = mode_of(frame)
        name = type(frame.message).__name__ if frame.message is not None else f"0x{frame.msg_id:02X}"
        detail = (mode.name if mode is not None else
                  _reason(frame.message.reason) if isinstance(frame.message, m.EpisodeEnd) else "")
        shown.append(("ACK " if index == ex.ack_at else "") + name + (f" {detail}" if detail else ""))
    return "frames: " + ", ".join(shown)


def matrix_row(name: str) -> Callable[[Probe], str]:
    def run(probe: Probe) -> str:
        makers = _commands(probe)
        passed: set[Mode] = set()
        failures: dict[Mode, list[str]] = {}
        for wanted in ORDER:
            for _ in range(TRIES_LEARNING if wanted == LE else TRIES):
                # A race (the agent left the mode between its last frame and the command) fails once; a wrong
                # agent fails every time: a cell fails when it failed twice and never passed.
                if wanted in passed or len(failures.get(wanted, ())) >= 2:
                    break
                reach(probe, wanted)
                before, problem = judge_cell(probe, name, makers[name], wanted)
                if before is None:
                    continue
                if problem:
                    failures.setdefault(before, []).append(problem)
                else:
                    passed.add(before)
        reach(probe, ID)
        problems = [found[0] for mode, found in failures.items() if mode not in passed]
        missed = [x.name for x in ORDER if x not in passed and x not in failures]
        expect(not problems, "; ".join(problems))
        expect(not missed, f"could not put the agent in {', '.join(missed)} in {TRIES}-{TRIES_LEARNING} tries "
               "(a virtual agent: a lower speed helps)")
        return "; ".join(f"{x.name} {_describe(MATRIX[name][x])}" for x in ORDER)
    return run


def _describe(cell: Cell) -> str:
    if cell.result != OK:
        return cell.result.name
    return "→" + "/".join(x.name for x in sorted(cell.after)) if cell.after else "ok"


for _name in MATRIX:
    check(f"modes.{_name.lower()}", SECTION, f"""{_name}: """ + "; ".join(
        f"{x.name} → {_describe(MATRIX[_name][x])}" for x in ORDER) + " (the command × mode matrix).",
          motion=True)(matrix_row(_name))


ANY_MODE = {
    "CMD_DUMP": lambda: m.DumpRequest(kind=int(DumpKind.POLICY), dump_id=0, offset=0, length=1),
    "PARAM_LIST": m.ParamListRequest, "PARAM_GET": lambda: m.ParamGet(index=0, name=""),
    "LOG_REQUEST": lambda: m.LogRequest(first_sample=1, end_sample=0),
}


@check("modes.any_mode", SECTION, """CMD_DUMP, PARAM_LIST, PARAM_GET, LOG_REQUEST: ACCEPTED in every mode (the
       command × mode matrix).""", motion=True)
def any_mode(probe: Probe) -> str:
    problems = []
    for wanted in (ID, HO, PA, LE):
        reach(probe, wanted)
        for name, make in ANY_MODE.items():
            ex = probe.command(make())
            if ex.result != OK:
                problems.append(f"{name} in {probe.mode_before(ex)}: {result_name(ex.result)}")
    reach(probe, ID)
    expect(not problems, "; ".join(problems))
    return "accepted in IDLE, HOVER, PAUSED, LEARNING"


@check("modes.hover_range", SECTION, """CMD_HOVER depth_m must lie in [0, 2.5] m; NaN or outside → BAD_VALUE. Value
       checks come first: a CMD_HOVER at 7 m in LEARNING is BAD_VALUE.""")
def hover_range(probe: Probe) -> str:
    for depth in (2.6, -0.1, float("nan")):
        ex = probe.command(m.Hover(depth_m=depth))
        expect(ex.result == AckResult.BAD_VALUE, f"CMD_HOVER {depth}: {result_name(ex.result)}, wanted BAD_VALUE")
    return "2.6, -0.1, NaN: BAD_VALUE"


@check("modes.idle_refusals", SECTION, """CMD_PAUSE in IDLE: NOT_ALLOWED; CMD_STOP: in IDLE and SURFACING it is
       ACCEPTED and changes nothing.""")
def idle_refusals(probe: Probe) -> str:
    if probe.current_mode() != ID:
        raise CheckSkipped(f"the agent is in {probe.current_mode().name}, not IDLE")
    for name, make in (("CMD_PAUSE", m.Pause), ("CMD_STOP", m.Stop)):
        _, problem = judge_cell(probe, name, make, ID)
        expect(not problem, problem)
    return "CMD_PAUSE refused, CMD_STOP accepted, still IDLE"


SHORT_EPISODE_S = 2.0


@check("modes.start_max_episodes", SECTION, """CMD_START max_episodes: the episode budget of this start; 0 means
       "the max_episodes parameter", whose 0 is "no limit". Each EPISODE_END that is not aborted uses one; when the
       budget is used up the agent surfaces.""", motion=True)
def start_max_episodes(probe: Probe) -> str:
    reach(probe, ID)
    # An episode that holds the depth lasts success_time_s (300 s of agent time: five minutes at --speed 1, past
    # the wait below): made short, the one episode ends within seconds however well the agent has learned.
    with overridden(probe, {"max_episodes": 1.0, "success_time_s": SHORT_EPISODE_S}):
        started = probe.accepted(m.StartLearning(max_episodes=0), "CMD_START 0 with max_episodes = 1")
        # From the ACK on: at full speed the one episode can be over within the read that brought the ACK, so
        # the frames read with it count (waiting from the end of what was read missed it: no EPISODE_END in 60 s).
        end = probe.wait_message(m.EpisodeEnd, started.ack_at + 1, probe.timeouts.mode_s)
        expect(end is not None, f"no EPISODE_END within {probe.timeouts.mode_s:g} s")
        assert end is not None
        shown = probe.wait_mode(set(Mode), end[0] + 1, probe.timeouts.heartbeat_s)
        expect(shown in (SU, ID), f"after the one episode the agent is in {shown}, wanted SURFACING")
    reach(probe, ID)
    return "one episode, then SURFACING"
