"""Link loss: after link_timeout_s without a valid frame the agent surfaces, if surface_on_link_loss (SPEC.md 4)."""

from __future__ import annotations

import time

from groundstation.check.agent import overridden, reach
from groundstation.check.probe import Probe, mode_of
from groundstation.check.registry import check, expect
from protocol import Mode
from protocol import messages as m

SECTION = "4 Link life cycle: link loss"
TIMEOUT_S = 0.5  # link_timeout_s while the check runs
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


@check("linkloss.surfaces", SECTION, """When it exceeds the parameter link_timeout_s (0 = never), the link is lost;
       if surface_on_link_loss is 1 and the agent is diving, it aborts any episode and surfaces (SURFACING). Link
       silence (link_timeout_s) is measured on the link's real clock.""", motion=True)
def surfaces(probe: Probe) -> str:
    reach(probe, Mode.HOVER)
    with overridden(probe, {"link_timeout_s": TIMEOUT_S, "surface_on_link_loss": 1.0}):
        # The agent's silence began when it read the last frame, no earlier than the probe wrote it. Counted from
        # the ACK instead, a slow read of that ACK (a pty's backlog, a loaded machine) ate into the window: CI saw a
        # correct agent surface 0.25 s after the ACK arrived.
        early_until = probe.last_send_s + TIMEOUT_S * 0.5
        early = _silence(probe, max(0.0, early_until - time.monotonic()))
        expect(Mode.SURFACING not in early, f"the agent surfaced less than {TIMEOUT_S * 0.5:g} s after the last "
               f"frame it was sent, before link_timeout_s = {TIMEOUT_S:g} s (agent time instead of the link's "
               "real clock?)")
        modes = _silence(probe, TIMEOUT_S * 0.5 + GRACE_S, {Mode.SURFACING, Mode.IDLE})
        expect(Mode.SURFACING in modes or Mode.IDLE in modes,
               f"after {TIMEOUT_S + GRACE_S:g} s of silence the agent still shows {modes[-1].name if modes else '-'}")
    reach(probe, Mode.IDLE)
    return f"surfaced after {TIMEOUT_S:g} s of silence, not before half of it"


def _mode_before(probe: Probe, index: int, start: int) -> Mode | None:
    """The last mode a frame from `start` up to (not including) `index` shows."""
    for frame in reversed(probe.frames(start, index)):
        if (mode := mode_of(frame)) is not None:
            return mode
    return None


@check("linkloss.unsigned_not_alive", SECTION, """for an agent with a key: since the last validly signed frame. An
       unsigned or refused non-command frame [...] does not count as a sign of life for link_timeout_s, so a
       stranger cannot keep a lost link "alive".""", key=True, motion=True)
def unsigned_not_alive(probe: Probe) -> str:
    reach(probe, Mode.HOVER)
    with overridden(probe, {"link_timeout_s": TIMEOUT_S, "surface_on_link_loss": 1.0}):
        start = scanned = probe.end
        deadline = time.monotonic() + TIMEOUT_S + GRACE_S
        with probe.quiet():
            # Each wait scans only what came since the last: rescanning from `start` grows with a fast agent's
            # frames until the scan alone outlasts the wait, and the agent, read no more, stands still.
            while time.monotonic() < deadline and probe.wait(lambda f: mode_of(f) == Mode.SURFACING, scanned, 0.1) \
                    is None:
                scanned = probe.end
                probe.send(m.Heartbeat(uptime_ms=0, mode=0, battery_mv=0, rx_frames=0, rx_rejects=0, rx_lost=0,
                                       log_first_sample=0, log_next_sample=0, episode=0, signing_rejects=0),
                           signer=False)
        modes = [x for f in probe.frames(start) if (x := mode_of(f)) is not None]
        if Mode.SURFACING not in modes and Mode.IDLE not in modes:
            # What the agent sent may still be on its way (a pseudo-terminal's buffers, a virtual agent at full
            # speed: seen taking seconds). The mode it was in when a signed TIMESYNC, the first sign of life after
            # the window, reached it is the last one shown before the reply.
            shown = _mode_before(probe, probe.barrier(), start)
            modes += [shown] if shown is not None else []
        expect(Mode.SURFACING in modes or Mode.IDLE in modes,
               f"unsigned HEARTBEATs every 0.1 s kept the link alive for {TIMEOUT_S + GRACE_S:g} s")
    reach(probe, Mode.IDLE)
    return "unsigned HEARTBEATs every 0.1 s did not keep the link alive"


@check("linkloss.off", SECTION, """if surface_on_link_loss is 1 [...] it surfaces.""", motion=True)
def off(probe: Probe) -> str:
    reach(probe, Mode.HOVER)
    with overridden(probe, {"link_timeout_s": TIMEOUT_S, "surface_on_link_loss": 0.0}):
        modes = _silence(probe, TIMEOUT_S * 3)
        expect(Mode.SURFACING not in modes, "the agent surfaced on link loss with surface_on_link_loss = 0")
    reach(probe, Mode.IDLE)
    return f"still hovering after {TIMEOUT_S * 3:g} s of silence"
