"""Runs the registered checks against one agent, in order, and collects one outcome per check."""

from __future__ import annotations

import importlib
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from groundstation.check.errors import CheckFailed, CheckSkipped
from groundstation.check.probe import Probe, Timeouts
from groundstation.check.registry import REGISTRY, Check, Outcome, Result
from groundstation.errors import GroundStationError, LinkError
from groundstation.links import make_link
from protocol import AckResult, ProtocolError
from protocol import messages as m


@dataclass(frozen=True)
class CheckOptions:
    url: str
    key: bytes | None = field(default=None, repr=False)
    allow_motion: bool = False
    timeouts: Timeouts = field(default_factory=Timeouts)
    only: tuple[str, ...] = ()  # check ids or id prefixes (a section group: "junk", "ack."); empty = all
    params: tuple[tuple[str, float], ...] = ()  # set after the handshake checks, put back at the end


@dataclass
class Report:
    url: str
    outcomes: list[Outcome]
    seconds: float
    aborted: str = ""  # why the run stopped early (the link died), "" if it ran to the end

    @property
    def failed(self) -> list[Outcome]:
        return [o for o in self.outcomes if o.result == Result.FAIL]

    def count(self, result: Result) -> int:
        return sum(o.result == result for o in self.outcomes)

    @property
    def passed(self) -> bool:
        return not self.failed and not self.aborted

    def as_dict(self) -> dict[str, object]:
        return {"url": self.url, "seconds": round(self.seconds, 3), "passed": self.passed, "aborted": self.aborted,
                "counts": {r.value: self.count(r) for r in Result},
                "checks": [o.as_dict() for o in self.outcomes]}


def selected(only: tuple[str, ...]) -> list[Check]:
    """The checks whose id equals or starts with one of `only` (all of them when `only` is empty)."""
    _load_checks()
    in_order = sorted(REGISTRY.checks, key=_run_position)
    if not only:
        return in_order
    return [c for c in in_order if any(c.id == o or c.id.startswith(o.rstrip(".") + ".") for o in only)]


# The run order: what needs nothing first, what moves the agent or changes its model last.
CHECK_MODULES = ("handshake", "junk", "timesync", "commands", "signing", "signing_resync", "parameters", "dumps",
                 "logreplay", "modes", "generations", "link_taken", "linkloss")


def _run_position(c: Check) -> int:
    """Where a check's module runs in CHECK_MODULES: the order a check was imported in must not decide (a module
    imported early, by a test, would run its checks before the handshake's)."""
    return CHECK_MODULES.index(c.run.__module__.rsplit(".", 1)[-1])


def _load_checks() -> None:
    for name in CHECK_MODULES:  # importing a module registers its checks
        importlib.import_module(f"groundstation.check.{name}")


def _skip_reason(c: Check, options: CheckOptions) -> str:
    if c.requires_motion and not options.allow_motion:
        return "would move the agent or change its model: --allow-motion"
    if c.requires_key and options.key is None:
        return "needs the agent's key: --key-file"
    return ""


def run_checks(options: CheckOptions, progress: Callable[[Outcome], None] = lambda _: None,
               waiting: Callable[[str], None] = lambda _: None) -> Report:
    """Open the link, run each selected check, close the link; a dead link ends the run (every check left FAILs).

    `waiting` is told the agent's reason each time it answers BUSY before the checks that send anything (a virtual
    agent building its program, SPEC.md s. 4): the run waits for it, it does not fail."""
    checks = selected(options.only)
    if not checks:
        raise GroundStationError(f"no check matches {', '.join(options.only)}")
    started = time.monotonic()
    link = make_link(options.url)
    link.open()
    probe = Probe(link, options.key, options.timeouts)
    outcomes: list[Outcome] = []
    aborted = ""
    prepared = awaited = False
    try:
        for c in checks:
            if not awaited and not aborted and c.id not in SILENT_FIRST:
                awaited = True
                try:
                    aborted = probe.await_program(waiting)
                except LinkError as e:
                    aborted = f"link: {e}"
            if not prepared and not aborted and not c.id.startswith(FIRST_GROUP):
                prepared = True
                aborted = _prepare(probe, options)
            outcome = _run_one(c, probe, options) if not aborted else Outcome(c, Result.FAIL, f"not run: {aborted}", 0)
            if outcome.result == Result.FAIL and outcome.detail.startswith("link: "):
                aborted = outcome.detail
            outcomes.append(outcome)
            progress(outcome)
        if not aborted:
            _restore(probe)
    finally:
        probe.close()
    return Report(options.url, outcomes, time.monotonic() - started, aborted)


FIRST_GROUP = "handshake."  # run before anything else is sent
SILENT_FIRST = ("handshake.agent_hello", "handshake.hello_repeat")  # the ground says nothing before these
MARK_AHEAD_S = 12.0  # SPEC.md 12: the persisted mark is the last accepted timestamp + 10 s


def _prepare(probe: Probe, options: CheckOptions) -> str:
    """Commands must get through (the key), and --param values are set; why the run cannot go on, or ""."""
    from groundstation.check.agent import require_set

    try:
        ex = probe.command(m.ParamGet(index=0, name=""))
        deadline = time.monotonic() + MARK_AHEAD_S
        while ex.result == AckResult.UNAUTHORIZED and options.key is not None and time.monotonic() < deadline:
            probe.settle(1.0)  # an agent's replay mark may lie up to 10 s ahead of a session that just ended
            ex = probe.command(m.ParamGet(index=0, name=""))
        if ex.ack is None:
            return f"the agent does not answer commands (no ACK within {probe.timeouts.reply_s:g} s)"
        if ex.ack.result == AckResult.UNAUTHORIZED:
            return (f"the agent refuses our signature (for {MARK_AHEAD_S:g} s): is --key-file its key?"
                    if options.key is not None
                    else "the agent refuses unsigned commands: give its key with --key-file")
        for name, value in options.params:
            from groundstation.check.agent import get_param

            probe.originals.setdefault(name, get_param(probe, name).value)
            require_set(probe, name, value)
    except CheckFailed as e:
        return str(e)
    except LinkError as e:
        return f"link: {e}"
    return ""


def _restore(probe: Probe) -> None:
    """Leave the agent as found: parameters the checks changed put back, at the surface if it moved."""
    from groundstation.check.agent import restore

    try:
        restore(probe)
    except (CheckFailed, GroundStationError):
        pass  # the report already says what went wrong; a failed clean-up is no extra finding


def _run_one(c: Check, probe: Probe, options: CheckOptions) -> Outcome:
    why = _skip_reason(c, options)
    if why:
        return Outcome(c, Result.SKIP, why, 0.0)
    start = time.monotonic()
    result, detail = Result.PASS, ""
    try:
        probe.pump(0.0)
        detail = c.run(probe) or ""
    except CheckFailed as e:
        result, detail = Result.FAIL, str(e)
    except CheckSkipped as e:
        result, detail = Result.SKIP, str(e)
    except LinkError as e:
        result, detail = Result.FAIL, f"link: {e}"
    except (ProtocolError, GroundStationError, ValueError, KeyError, AssertionError) as e:
        result, detail = Result.FAIL, f"{type(e).__name__}: {e}"
    return Outcome(c, result, detail, time.monotonic() - start)
