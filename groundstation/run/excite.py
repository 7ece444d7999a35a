"""The identification manoeuvre of `dive fit --excite`: hover at a few depths in turn, then reversals of the hover
depth at several amplitudes, all recorded, then surface.

Each change of hover depth is a step of the recovery controller's target: the gear swings hard, the hull
accelerates, runs and settles, which is what the plant fit needs (added mass, drag, neutral angle,
compressibility, the actuator's rate). The reversals flip the target a few centimetres up and down, short holds
each: every flip reverses the commanded actuator at once by an amount that grows with the flip (52 deg per
metre of it, and up to the inner layer's 2 x 3 deg), so the gear's play is taken up and released again and again at
several amplitudes while the hull moves (backlash, dead band), and the steps come in several sizes (the port's
lag). The agent's own `max_dive_s` is set to the manoeuvre's limit, so it surfaces by itself even if the link
fails; any surprise (another mode, too deep, a lost link) surfaces it at once.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from groundstation.errors import GroundStationError, LinkError
from groundstation.links import make_link
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.run.job import session_info
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import Mode
from protocol import messages as m

HOVER_LIMITS_M = (0.05, 2.5)  # CMD_HOVER's range (SPEC), above the surface band a fit cannot use
DEPTH_MARGIN_M = 0.15  # an overshoot past the deepest hover depth that is still the controller's, not a fault
FLIPS = 4  # hover targets per reversal amplitude: down, back, down, back (two full reversals of the gear each)
WALL_PER_AGENT_S = 3.0  # a step may take this many wall seconds per agent second (speed 1) before it is a fault


@dataclass(frozen=True)
class ExciteConfig:
    url: str | None = None
    depths_m: tuple[float, ...] = (0.3, 0.6, 0.4, 0.8, 0.3)
    hold_s: float = 30.0  # agent time at each depth
    # After the depths: the target flipped this much deeper than the last depth and back, FLIPS times per
    # amplitude, reversal_hold_s of agent time each (the flips of 2, 5 and 10 cm reverse the command at once by
    # about 6, 9 and 11 deg: 52 deg per metre and the inner layer's swing; the family's backlash is 0-2 deg).
    reversals_m: tuple[float, ...] = (0.02, 0.05, 0.1)
    reversal_hold_s: float = 3.0
    max_depth_m: float = 1.0  # no hover depth beyond it; deeper than it plus a margin is a fault
    recorder: RecorderConfig = field(default_factory=RecorderConfig)
    session: SessionConfig = field(default_factory=SessionConfig)

    def steps(self) -> list[tuple[float, float]]:
        """(hover depth, agent seconds) in the order flown: the depths, then the reversals about the last."""
        steps = [(depth, self.hold_s) for depth in self.depths_m]
        if not self.depths_m:
            return steps
        last = self.depths_m[-1]
        for amplitude in self.reversals_m:
            steps += [(last + amplitude if k % 2 == 0 else last, self.reversal_hold_s) for k in range(FLIPS)]
        return steps

    @property
    def max_dive_s(self) -> float:
        """The agent's own dive limit: the manoeuvre's agent time thrice, and a minute.

        A hold ends when the ground station has seen hold_s of agent time, but an agent faster than real time
        (a simulator at --speed max) runs ahead by what the link buffers and what it flies while the command is on
        its way: each hold is that much longer in agent time. Our agents wait for a ground that reads slowly
        (flow control), so that is a few kB, seconds of agent time, whatever the machine's load.
        """
        return 3.0 * sum(hold for _, hold in self.steps()) + 60.0


def check(config: ExciteConfig) -> None:
    """A GroundStationError naming the first setting that cannot be flown (before anything connects)."""
    if not config.depths_m:
        raise GroundStationError("--depths names no depth")
    if not config.hold_s > 0:
        raise GroundStationError(f"--hold must be positive (got {config.hold_s:g})")
    if config.reversals_m and not config.reversal_hold_s > 0:
        raise GroundStationError(f"--reversal-hold must be positive (got {config.reversal_hold_s:g})")
    for amplitude in config.reversals_m:
        if not amplitude > 0:
            raise GroundStationError(f"a reversal of {amplitude:g} m is no reversal (--reversals: amplitudes > 0)")
    for depth, _ in config.steps():
        if not HOVER_LIMITS_M[0] <= depth <= min(HOVER_LIMITS_M[1], config.max_depth_m):
            raise GroundStationError(f"hover depth {depth:g} m is outside [{HOVER_LIMITS_M[0]:g}, "
                                     f"{min(HOVER_LIMITS_M[1], config.max_depth_m):g}] m (--max-depth; the "
                                     f"reversals go --reversals deeper than the last of --depths)")


class _Watch:
    """Session listener: the agent's latest time, depth and mode, and the first fault seen."""

    def __init__(self, max_depth_m: float) -> None:
        self.max_depth_m = max_depth_m
        self.t_us = -1
        self.mode = -1
        self.fault = ""
        self.changed = threading.Event()
        self.hovering = False  # set once our first CMD_HOVER is answered: SURFACING after that is a fault

    def on_received(self, received: Received) -> None:
        msg = received.message
        if isinstance(msg, m.Sample) and not received.backfilled:
            self.t_us, self.mode = msg.t_us, msg.mode
            if msg.depth_m > self.max_depth_m and not self.fault:
                self.fault = f"depth {msg.depth_m:.2f} m, deeper than {self.max_depth_m:.2f} m"
            elif self.hovering and msg.mode in (Mode.SURFACING, Mode.IDLE) and not self.fault:
                self.fault = f"the agent left HOVER for {Mode(msg.mode).name}"
            self.changed.set()

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.LINK_LOST and not self.fault:
            self.fault = f"link lost: {event.detail}"
            self.changed.set()


def excite(config: ExciteConfig, on_step: Callable[[float, float], None] | None = None) -> list[Path]:
    """Fly the manoeuvre and record it; returns the recording's files. Raises GroundStationError on a fault, after
    telling the agent to surface (the recording up to there is kept)."""
    check(config)
    link = make_link(config.url)
    recorder = Recorder(config.recorder, session_info(link.url))
    steps = config.steps()
    watch = _Watch(max(depth for depth, _ in steps) + DEPTH_MARGIN_M)
    session = Session(link, config.session, [recorder, watch])
    try:
        session.connect()
        if "max_dive_s" in session.params:
            session.set_param("max_dive_s", repr(config.max_dive_s))
        recorder.set_parameters(session.params.values())
        for depth, hold_s in steps:
            if on_step is not None:
                on_step(depth, hold_s)
            session.command(m.Hover(depth_m=depth))
            watch.hovering = True
            _hold(watch, session, hold_s)
            if watch.fault or session.failure is not None:
                break
    except (GroundStationError, OSError) as e:
        watch.fault = watch.fault or str(e)
    finally:
        watch.hovering = False  # SURFACING from here on is ours
        _surface(session)
        try:
            session.request_backfill(5.0, final=True)
        except (GroundStationError, OSError):
            pass  # what arrived live is recorded; the fit uses what is there
        session.close()
        recorder.close()
    if session.failure is not None and not watch.fault:
        watch.fault = str(session.failure)
    if watch.fault:
        where = f"; recorded so far: {recorder.paths[-1]}" if recorder.paths else ""
        raise GroundStationError(f"excitation stopped, the agent told to surface: {watch.fault}{where}")
    return list(recorder.paths)


def _hold(watch: _Watch, session: Session, hold_s: float) -> None:
    """Wait until hold_s of agent time has passed since now (or a fault, or far too much wall time)."""
    began_wall = time.monotonic()
    start_us = watch.t_us
    while not watch.fault and session.failure is None:
        if start_us < 0:
            start_us = watch.t_us
        elif watch.t_us - start_us >= hold_s * 1e6:
            return
        if time.monotonic() - began_wall > WALL_PER_AGENT_S * hold_s + 30.0:
            watch.fault = f"no {hold_s:g} s of agent time within {WALL_PER_AGENT_S * hold_s + 30.0:.0f} s"
            return
        watch.changed.wait(0.2)
        watch.changed.clear()


def _surface(session: Session) -> None:
    try:
        session.command(m.Surface())
    except (GroundStationError, OSError, LinkError):
        pass  # the agent surfaces by itself at max_dive_s, or on link loss where it is set to
