"""The conformance probe's waits: a wait reads the link even when its time is up before it got to read."""

from __future__ import annotations

import threading
import time

from groundstation.check.modes import judge_cell
from groundstation.check.probe import Probe, mode_of
from groundstation.links.memory import MemoryLink
from protocol import AckResult, EndReason, FrameEncoder, Mode, StreamDecoder
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


def test_a_stop_in_learning_without_its_aborted_episode_says_what_came_instead() -> None:
    """The command x mode matrix judges CMD_STOP in LEARNING on the EPISODE_END aborted that must follow its ACK; an
    agent that ends the episode as a failure instead fails the cell with the frames it judged on, so a rare miss in
    CI can be told from a race of the check."""
    probe, agent = _probe_and_agent()
    encoder = FrameEncoder()
    agent.send(encoder.encode(_heartbeat(Mode.LEARNING)).wire)
    probe.pump(0.5)

    def wrong_agent() -> None:
        decoder = StreamDecoder(agent=True)
        while not (frames := decoder.feed(agent.recv(5.0))):
            pass
        command = frames[0]
        agent.send(encoder.encode(m.Ack(cmd_msg_id=command.msg_id, cmd_seq=command.seq,
                                        result=int(AckResult.ACCEPTED), reason="")).wire)
        agent.send(encoder.encode(m.EpisodeEnd(episode=4, reason=int(EndReason.FAILURE))).wire)
        agent.send(encoder.encode(_heartbeat(Mode.SURFACING)).wire)

    answering = threading.Thread(target=wrong_agent)
    answering.start()
    before, problem = judge_cell(probe, "CMD_STOP", m.Stop, Mode.LEARNING)
    answering.join()
    assert before == Mode.LEARNING
    assert problem == ("CMD_STOP in LEARNING: no EPISODE_END aborted after the ACK (the first was FAILURE; frames: "
                       "Heartbeat LEARNING, ACK Ack, EpisodeEnd FAILURE, Heartbeat SURFACING)"), problem
