"""What several checks need from the agent: its parameter table, a parameter set and restored, a mode reached."""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from groundstation.check.errors import CheckFailed, CheckSkipped
from groundstation.check.probe import START_AT_REST, Exchange, Probe, result_name
from protocol import AckResult, Mode
from protocol import messages as m
from protocol import parameters as spec_params

HOVER_DEPTH_M = 0.5  # where checks hold the agent (inside any tank the paper's agent dives in)
DEEP_M = 0.4  # deep enough that surfacing takes the agent seconds, not one step


def param_table(probe: Probe) -> dict[str, m.ParamValue]:
    """Every parameter by name, from PARAM_LIST (the ACK, then one PARAM_VALUE per parameter)."""
    ex = probe.accepted(m.ParamListRequest())
    first = probe.wait_message(m.ParamValue, ex.ack_at, probe.timeouts.reply_s)
    if first is None:
        raise CheckFailed("PARAM_LIST: no PARAM_VALUE after the ACK")
    count = first[1].count
    found = probe.wait(lambda _: len(probe.messages(m.ParamValue, ex.ack_at)) >= count, ex.ack_at,
                       probe.timeouts.reply_s)
    values = probe.messages(m.ParamValue, ex.ack_at)
    if found is None or len(values) < count:
        raise CheckFailed(f"PARAM_LIST: {len(values)} of {count} PARAM_VALUEs arrived")
    return {v.name: v for v in values[:count]}


def get_param(probe: Probe, name: str) -> m.ParamValue:
    ex = probe.accepted(m.ParamGet(index=-1, name=name), f"PARAM_GET {name}")
    found = probe.wait_message(m.ParamValue, ex.ack_at, probe.timeouts.reply_s, lambda v: v.name == name)
    if found is None:
        raise CheckFailed(f"PARAM_GET {name}: no PARAM_VALUE after the ACK")
    return found[1]


def has_param(probe: Probe, name: str) -> bool:
    ex = probe.command(m.ParamGet(index=-1, name=name))
    return ex.result == AckResult.ACCEPTED


def set_param(probe: Probe, name: str, value: float) -> tuple[Exchange, m.ParamValue | None]:
    """PARAM_SET by name; the PARAM_VALUE that follows an ACCEPTED (None after a NACK or if none came)."""
    ex = probe.command(m.ParamSet(index=-1, value=value, name=name))
    if ex.ack is None:
        raise CheckFailed(f"PARAM_SET {name}={value}: no ACK within {probe.timeouts.reply_s:g} s")
    if ex.ack.result != AckResult.ACCEPTED:
        return ex, None
    found = probe.wait_message(m.ParamValue, ex.ack_at, probe.timeouts.reply_s, lambda v: v.name == name)
    if name in LEARNER_PARAMS:
        await_restart(probe)
    return ex, found[1] if found is not None else None


LEARNER_PARAMS = frozenset(p.name for p in spec_params.PARAMS if p.learner)
RESTART_WAIT_S = 180.0  # a virtual agent on a cold compile cache, under load, builds a new learner's code this long


def await_restart(probe: Probe) -> None:
    """After an accepted learner change the agent may restart its learner (SPEC 1.3 s. 4, answer time: a learner
    restart after its ACK may take long, and what arrives meanwhile is answered once it is done): a TIMESYNC
    answered says it is done, so the next command's ACK is not waited for too briefly (a false failure)."""
    start = probe.end
    probe.send(m.Timesync(origin_us=1))
    if probe.wait_message(m.Timesync, start, RESTART_WAIT_S) is None:
        raise CheckFailed(f"no answer for {RESTART_WAIT_S:g} s after a learner parameter change")


def require_set(probe: Probe, name: str, value: float) -> m.ParamValue:
    ex, reply = set_param(probe, name, value)
    if reply is None:
        raise CheckFailed(f"PARAM_SET {name}={value}: {result_name(ex.result)}"
                          + (f" ({ex.ack.reason})" if ex.ack and ex.ack.reason else "") + ", wanted ACCEPTED")
    return reply


@contextmanager
def overridden(probe: Probe, values: dict[str, float]) -> Iterator[dict[str, m.ParamValue]]:
    """Parameters set for the block and put back afterwards (in reverse order)."""
    old: list[tuple[str, float]] = []
    try:
        applied = {}
        for name, value in values.items():
            old.append((name, get_param(probe, name).value))
            applied[name] = require_set(probe, name, value)
        yield applied
    finally:
        for name, value in reversed(old):
            set_param(probe, name, value)


def states(probe: Probe) -> int:
    """S = z_cells * zdot_cells * act_bins + 1 (the terminal state last)."""
    product = 1
    for name in ("z_cells", "zdot_cells", "act_bins"):
        product *= int(get_param(probe, name).value)
    return product + 1


# ---------------------------------------------------------------------- modes
def go_idle(probe: Probe) -> None:
    """CMD_SURFACE unless IDLE already, then wait until the agent shows it is at the surface (IDLE).

    "IDLE already" is what the newest frame shows after the last command that moved the agent (Probe.pump forgets
    the mode at such an ACK): a CMD_SURFACE at the surface shows SURFACING for a step first (SPEC.md 6)."""
    if probe.current_mode() == Mode.IDLE:
        return
    ex = probe.accepted(m.Surface(), "CMD_SURFACE (to reach IDLE)")
    _wait(probe, {Mode.IDLE}, ex.ack_at)


def hover_depth(probe: Probe) -> float:
    return HOVER_DEPTH_M


def reach(probe: Probe, target: Mode) -> None:
    """Bring the agent into `target`: send what leads there and wait until a frame after the ACK shows it.

    RECOVERING, LEARNING and SURFACING end on their own (within milliseconds on a virtual agent at full speed), so
    the caller judges its next command by the mode it really met (Probe.mode_before) and tries again if needed.
    """
    mode = probe.current_mode()
    if mode == target and target in (Mode.IDLE, Mode.HOVER, Mode.PAUSED):
        return
    if target == Mode.IDLE:
        go_idle(probe)
    elif target == Mode.HOVER:
        def settle() -> None:
            if probe.current_mode() not in (Mode.IDLE, Mode.PAUSED, Mode.HOVER):
                go_idle(probe)

        settle()
        _enter(probe, m.Hover(depth_m=hover_depth(probe)), {Mode.HOVER}, settle)
    elif target == Mode.SURFACING:
        if mode != Mode.HOVER:
            reach(probe, Mode.HOVER)
        deep = probe.wait_message(m.Sample, probe.end, probe.timeouts.mode_s, lambda s: s.depth_m > DEEP_M)
        if deep is None:
            raise CheckFailed(f"the agent did not get deeper than {DEEP_M} m within {probe.timeouts.mode_s:g} s")
        # A virtual agent at full speed surfaces within a millisecond: the caller's command goes right behind.
        probe.defer(m.Surface(), Mode.SURFACING)
    elif target == Mode.PAUSED:
        def moving() -> None:
            if probe.current_mode() not in (Mode.LEARNING, Mode.RECOVERING):
                _start(probe)

        moving()
        _enter(probe, m.Pause(), {Mode.PAUSED}, moving)
    elif target == Mode.RECOVERING:
        _start_at_rest(probe, False)
        _start(probe)
    elif target == Mode.LEARNING:
        if _start_at_rest(probe, True):
            # An episode starts at once (EPISODE_START right after the ACK): the caller's command goes right behind,
            # before a virtual agent at full speed has ended the episode.
            if probe.current_mode() not in (Mode.IDLE, Mode.HOVER, Mode.PAUSED):
                go_idle(probe)
            probe.notes["moved"] = 1.0
            probe.defer(m.StartLearning(max_episodes=0), Mode.LEARNING)
            return
        # A real agent recovers first (or gives up and surfaces): the caller judges the mode its command meets.
        _wide_region(probe)
        if probe.current_mode() != Mode.RECOVERING:
            _start(probe)
        # After the start: the SURFACING/IDLE frames of the go_idle inside _start must not end the wait.
        since = probe.end
        deadline = time.monotonic() + probe.timeouts.mode_s
        while True:
            left = deadline - time.monotonic()
            shown = probe.wait_mode({Mode.LEARNING, Mode.SURFACING, Mode.IDLE}, since, max(left, 0.0))
            if shown != Mode.LEARNING:
                return  # gave up recovering, or the time is up: the caller sees which mode its command met
            since = probe.end
            probe.drain()  # behind a fast agent's backlog the episode may be over already: wait for a current one
            if probe.mode == Mode.LEARNING:
                return


ENTER_TRIES = 4  # a command refused because the agent was passing through a mode that ends on its own is retried


def _enter(probe: Probe, command: m.Message, modes: set[Mode], prepare: Callable[[], None] = lambda: None) -> Mode:
    """Send a command that must be ACCEPTED; the first of `modes` shown after its ACK.

    A NOT_ALLOWED_IN_MODE from an agent that the frames around the ACK show in a mode that ends on its own
    (SURFACING after a CMD_SURFACE at the surface, an episode that just ended) is the check's race, not the
    agent's fault (issue 26, D2): `prepare` brings the agent back to a mode the command needs and it is sent again.
    """
    probe.notes["moved"] = 1.0
    what = f"{command.DEFINITION.name} (to reach {'/'.join(x.name for x in sorted(modes))})"
    ack = m.Ack(cmd_msg_id=0, cmd_seq=0, result=0, reason="")
    met: Mode | None = None
    for _ in range(ENTER_TRIES):
        ex = probe.command(command)
        if ex.ack is None:
            raise CheckFailed(f"{what}: no ACK within {probe.timeouts.reply_s:g} s")
        ack = ex.ack
        if ack.result == AckResult.ACCEPTED:
            return _wait(probe, modes, ex.ack_at)
        met = probe.mode_before(ex)
        if ack.result != AckResult.NOT_ALLOWED_IN_MODE or met not in (None, *TRANSIENT):
            break
        prepare()
    met_name = met.name if met is not None else "a mode its frames do not show"
    raise CheckFailed(f"{what}: refused with {result_name(ack.result)} ({ack.reason}) in {met_name}")


TRANSIENT = (Mode.SURFACING, Mode.LEARNING, Mode.RECOVERING)  # modes an agent leaves on its own


def _start(probe: Probe) -> Mode:
    """CMD_START; returns once the agent shows RECOVERING (or LEARNING, when episodes start at once)."""
    def settle() -> None:
        if probe.current_mode() not in (Mode.IDLE, Mode.HOVER, Mode.PAUSED):
            go_idle(probe)

    settle()
    return _enter(probe, m.StartLearning(max_episodes=0), {Mode.RECOVERING, Mode.LEARNING}, settle)


def _start_at_rest(probe: Probe, wanted: bool) -> bool:
    """Set the simulator-only start_at_rest (1: an episode starts at once, no RECOVERING) if the agent lets us;
    whether episodes now start at once. The first value seen is put back by restore()."""
    notes = probe.notes
    if START_AT_REST not in notes:
        ex = probe.command(m.ParamGet(index=-1, name=START_AT_REST))
        found = (probe.wait_message(m.ParamValue, ex.ack_at, probe.timeouts.reply_s, lambda v: v.name == START_AT_REST)
                 if ex.result == AckResult.ACCEPTED else None)
        value = found[1] if found is not None else None
        notes[START_AT_REST] = value.value if value is not None and value.maximum > value.minimum else None
        probe.originals.setdefault(START_AT_REST, notes[START_AT_REST])
    current = notes[START_AT_REST]
    if current is None:
        return False
    if bool(current) != wanted:
        if probe.current_mode() in (Mode.LEARNING, Mode.RECOVERING):
            go_idle(probe)  # a mission parameter, but changed only between episodes
        require_set(probe, START_AT_REST, float(wanted))
        notes[START_AT_REST] = float(wanted)
    return wanted


# A learning region this wide is left rarely, so an episode lasts long enough for a command to meet it even on an
# agent that runs far faster than real time (start depths stay within target ± 0.95 z_tol_m: 0.07-0.73 m at 0.4 m).
WIDE_REGION = {"z_tol_m": 0.35, "zdot_tol_mps": 0.5}


def _wide_region(probe: Probe) -> None:
    """Widen the learning region once per run (learner parameters: only in IDLE); restore() puts it back."""
    if probe.notes.get("wide_region"):
        return
    probe.notes["wide_region"] = 1.0
    go_idle(probe)
    for name, value in WIDE_REGION.items():
        current = get_param(probe, name).value
        ex, _ = set_param(probe, name, value)
        if ex.result == AckResult.ACCEPTED:
            probe.originals.setdefault(name, current)


def restore(probe: Probe) -> None:
    """Leave the agent at the surface if it moved, then put back the parameters the run changed."""
    if probe.notes.get("moved"):
        go_idle(probe)
    for name, value in probe.originals.items():
        if value is not None:
            set_param(probe, name, value)


def _wait(probe: Probe, modes: set[Mode], since: int) -> Mode:
    shown = probe.wait_mode(modes, since)
    if shown is None:
        names = "/".join(sorted(x.name for x in modes))
        raise CheckFailed(f"the agent did not reach {names} within {probe.timeouts.mode_s:g} s")
    return shown


def skip_unless(condition: bool, why: str) -> None:
    if not condition:
        raise CheckSkipped(why)


def is_f32(value: float) -> bool:
    """value is exactly an f32 widened to f64."""
    import struct

    if not math.isfinite(value):
        return True
    return bool(struct.unpack("<f", struct.pack("<f", value))[0] == value)
