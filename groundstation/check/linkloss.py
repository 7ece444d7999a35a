"""Link loss: after link_timeout_s without a valid frame the agent surfaces, if surface_on_link_loss (SPEC.md 4)."""

from __future__ import annotations

from groundstation.check.agent import overridden, reach
from groundstation.check.probe import Probe, mode_of
from groundstation.check.registry import check, expect
from protocol import Mode

SECTION = "4 Link life cycle: link loss"
TIMEOUT_S = 1.0  # link_timeout_s while the check runs
GRACE_S = 3.0  # wall seconds past the timeout the agent may take to notice


def _silence(probe: Probe, seconds: float, until: set[Mode] | None = None) -> list[Mode]:
    """Send nothing for `seconds` of wall time (less once a mode in `until` shows); the modes shown meanwhile."""
    start = probe.end
    with probe.quiet():
        if until:
            probe.wait(lambda f: mode_of(f) in until, start, seconds)
        else:
            probe.settle(seconds)
    return [x for f in probe.frames(start) if (x := mode_of(f)) is not None]


@check("linkloss.surfaces", SECTION, """The agent counts time since the last valid frame from the ground; after the
       parameter link_timeout_s (0 = never) it aborts learning and surfaces (mode SURFACING) if surface_on_link_loss
       is set. Link silence is measured on the link's real clock (decisions: O10).""", motion=True)
def surfaces(probe: Probe) -> str:
    reach(probe, Mode.HOVER)
    with overridden(probe, {"link_timeout_s": TIMEOUT_S, "surface_on_link_loss": 1.0}):
        early = _silence(probe, TIMEOUT_S * 0.5)
        expect(Mode.SURFACING not in early, f"the agent surfaced after {TIMEOUT_S * 0.5:g} s of silence, before "
               f"link_timeout_s = {TIMEOUT_S:g} s (agent time instead of the link's real clock?)")
        modes = _silence(probe, TIMEOUT_S * 0.5 + GRACE_S, {Mode.SURFACING, Mode.IDLE})
        expect(Mode.SURFACING in modes or Mode.IDLE in modes,
               f"after {TIMEOUT_S + GRACE_S:g} s of silence the agent still shows {modes[-1].name if modes else '-'}")
    reach(probe, Mode.IDLE)
    return f"surfaced after {TIMEOUT_S:g} s of silence, not before half of it"


@check("linkloss.off", SECTION, """[The agent surfaces on link loss only] if surface_on_link_loss is set.""",
       motion=True)
def off(probe: Probe) -> str:
    reach(probe, Mode.HOVER)
    with overridden(probe, {"link_timeout_s": TIMEOUT_S, "surface_on_link_loss": 0.0}):
        modes = _silence(probe, TIMEOUT_S + 1.0)
        expect(Mode.SURFACING not in modes, "the agent surfaced on link loss with surface_on_link_loss = 0")
    reach(probe, Mode.IDLE)
    return f"still hovering after {TIMEOUT_S + 1.0:g} s of silence"
