"""The conformance probe's waits: a wait reads the link even when its time is up before it got to read."""

from __future__ import annotations

import time

from groundstation.check.probe import Probe, mode_of
from groundstation.links.memory import MemoryLink
from protocol import FrameEncoder, Mode
from protocol import messages as m
from protocol.decoder import Frame


def _heartbeat(mode: Mode) -> m.Heartbeat:
    return m.Heartbeat(uptime_ms=1, mode=int(mode), battery_mv=3700, rx_frames=0, rx_rejects=0, rx_lost=0,
                       log_first_sample=0, log_next_sample=0, episode=0, signing_rejects=0)


def _probe_and_agent() -> tuple[Probe, MemoryLink]:
    ground, agent = MemoryLink.pair()
    ground.open()
    agent.open()
    return Probe(ground), agent


def test_a_wait_with_no_time_left_still_reads_what_arrived() -> None:
    probe, agent = _probe_and_agent()
    agent.send(FrameEncoder().encode(_heartbeat(Mode.SURFACING)).wire)
    found = probe.wait(lambda f: mode_of(f) == Mode.SURFACING, probe.end, 0.0)
    assert found is not None and found[0] == 0


def test_a_scan_that_outlasts_the_wait_does_not_stop_the_reading() -> None:
    """A wait whose scan of earlier frames takes longer than its timeout still reads the link once more: a probe
    that rescans a long history would otherwise never read again, and an agent at --speed max would stand still."""
    probe, agent = _probe_and_agent()
    encoder = FrameEncoder()
    agent.send(encoder.encode(_heartbeat(Mode.HOVER)).wire)
    assert probe.wait(lambda f: mode_of(f) == Mode.HOVER, probe.end, 1.0) is not None
    agent.send(encoder.encode(_heartbeat(Mode.SURFACING)).wire)

    def slow_surfacing(frame: Frame) -> bool:
        time.sleep(0.02)  # the scan of the old frame alone outlasts the wait's 0.01 s
        return mode_of(frame) == Mode.SURFACING

    found = probe.wait(slow_surfacing, 0, 0.01)
    assert found is not None and found[0] == 1
