"""`dive check`'s link-loss checks against a real `dive sim` over TCP, with the probe's reading slowed where CI saw it.

A loaded machine can leave the ACK of the last parameter set unread for a while: the agent's silence began when it
read that PARAM_SET, not when the probe read the ACK, so a correct agent may surface soon after the ACK arrives.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from groundstation.check import agent as check_agent
from groundstation.check import linkloss
from groundstation.check.probe import Probe
from groundstation.links import Link, make_link
from protocol import Mode
from tests.groundstation.check_helpers import BROKEN_AGENT, agent, by_result, check

ACK_READ_LATE_S = 0.35  # more than half of the check's link_timeout_s, less than all of it


class LateReads:
    """A link whose next read, once armed, comes ACK_READ_LATE_S late (a busy ground station)."""

    def __init__(self, link: Link) -> None:
        self.link = link
        self.armed = False

    def __getattr__(self, name: str) -> object:
        return getattr(self.link, name)

    def recv(self, timeout_s: float) -> bytes:
        if self.armed:
            self.armed = False
            time.sleep(ACK_READ_LATE_S)
        return self.link.recv(timeout_s)


@pytest.mark.slow
def test_an_ack_read_late_does_not_make_a_correct_agent_surface_early(tmp_path: Path,
                                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    with agent(tmp_path, "--tcp", "127.0.0.1:0", "--preset", "paper", "--seed", "3") as url:
        link = LateReads(make_link(url))
        link.open()
        probe = Probe(link)  # type: ignore[arg-type]
        assert probe.await_program() == ""  # its program built (a starting agent answers BUSY)
        original_set = check_agent.require_set

        def set_then_read_late(p: Probe, name: str, value: float) -> object:
            link.armed = name == "surface_on_link_loss"  # the last set before the silence
            return original_set(p, name, value)

        monkeypatch.setattr(check_agent, "require_set", set_then_read_late)
        try:
            sent_before = probe.last_send_s
            assert "surfaced after" in linkloss.surfaces(probe)
            assert probe.last_send_s > sent_before
            assert probe.current_mode() == Mode.IDLE
        finally:
            probe.close()


@pytest.mark.slow
def test_an_agent_that_measures_silence_in_agent_time_fails(tmp_path: Path) -> None:
    script = [str(BROKEN_AGENT), "silence-in-agent-time", "serve"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", script=script) as url:
        code, report = check(url, "--only", "linkloss.surfaces", "--allow-motion")
    assert code == 1
    assert by_result(report, "FAIL") == [
        "linkloss.surfaces: the agent surfaced less than 0.25 s after the last frame it was sent, before "
        "link_timeout_s = 0.5 s (agent time instead of the link's real clock?)"], report
