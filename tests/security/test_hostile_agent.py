"""A hostile (or broken) agent: no single frame it sends ends a recording or hangs a run (issue 25 C2, C3).

A fake agent over real TCP, the real main job, the recording read back with the mcap library.
"""

from __future__ import annotations

import time
from pathlib import Path

from groundstation.errors import ListenerError
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.security.attack import RunInThread, recorded, sample_indices
from tests.waiting import wait_for

U64_MAX = 2**64 - 1


def test_a_timesync_of_2_64_is_ignored_counted_and_the_recording_goes_on(tmp_path: Path) -> None:
    agent = FakeAgent()
    try:
        job = RunInThread(agent.url, tmp_path)
        assert wait_for(lambda: agent.learning and agent.sample > 100)
        time.sleep(1.1)  # a true TIMESYNC first: the clock model is synced when the lies come
        agent.lying_timesyncs = 2  # its answers to the ground's requests: receive = transmit = 2^64-1
        agent.send(m.Timesync(origin_us=U64_MAX, receive_us=1, transmit_us=2))  # an answer to nothing sent
        assert wait_for(lambda: agent.lying_timesyncs == 0, 5.0)
        lied_at = agent.sample
        assert wait_for(lambda: agent.sample > lied_at + 150)
        job.stop()
    finally:
        agent.close()
    assert job.error is None, job.error
    assert sample_indices(tmp_path) == list(range(agent.sample))  # every sample, before and after the lies
    topics = recorded(tmp_path)
    assert topics["/link"][-1][2]["link"]["timesyncs_ignored"] == 3
    now_ns = time.time_ns()
    # every frame's agent time stays a time near now (an hour either side), none moved by centuries
    for _, publish_ns, _ in topics["/agent/SAMPLE"]:
        assert abs(publish_ns - now_ns) < 3600e9
    errors = [body["detail"] for _, _, body in topics.get("/event", []) if body["kind"] == "error"]
    assert any("TIMESYNC ignored" in e for e in errors)


class _Raises:
    """A listener that fails on the 200th frame, as a recorder bug would."""

    def __init__(self) -> None:
        self.frames = 0

    def on_received(self, received: Received) -> None:
        self.frames += 1
        if self.frames >= 200:
            raise OverflowError("argument out of range")

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


def test_a_listener_that_raises_stops_the_run_and_the_agent_with_its_reason(tmp_path: Path) -> None:
    agent = FakeAgent()
    try:
        job = RunInThread(agent.url, tmp_path, listeners=[_Raises()])
        job.join(20)  # by itself: nobody stops it
    finally:
        agent.close()
    assert isinstance(job.error, ListenerError), job.error
    assert "_Raises failed: OverflowError: argument out of range; stopping the run" in str(job.error)
    assert "CMD_STOP" in agent.executed and not agent.learning  # the agent does not learn on unrecorded
    assert sample_indices(tmp_path) == list(range(agent.sample))  # what the agent made is recorded


def test_a_heartbeat_claiming_a_next_sample_near_2_32_neither_hangs_nor_floods(tmp_path: Path) -> None:
    agent = FakeAgent()
    try:
        job = RunInThread(agent.url, tmp_path)
        assert wait_for(lambda: agent.learning and agent.sample > 100)
        before = agent.log_requests
        agent.send(m.Heartbeat(uptime_ms=agent.now_us() // 1000, mode=1, battery_mv=4000, rx_frames=0, rx_rejects=0,
                               rx_lost=0, log_first_sample=0, log_next_sample=2**32 - 2, episode=agent.episode,
                               signing_rejects=0))
        lied_at, lied_s = agent.sample, time.monotonic()
        assert wait_for(lambda: agent.sample > lied_at + 300)
        asked, elapsed_s = agent.log_requests - before, time.monotonic() - lied_s
        job.stop(20)  # ends within the final backfill's bounded wait, not after 8.4 M ranges a tick
    finally:
        agent.close()
    assert isinstance(job.error, type(None)), job.error
    # at most 16 requests a round, 2 rounds a second (the claimed window: at most MAX_LOG_SAMPLES / 512 = 128 ranges)
    assert asked <= 16 * (2 * elapsed_s + 2), (asked, elapsed_s)
    assert sample_indices(tmp_path) == list(range(agent.sample))  # every sample the agent made is recorded


def test_a_planner_told_of_2_32_samples_plans_a_bounded_backfill() -> None:
    from groundstation.session.gaps import MAX_LOG_SAMPLES, REQUEST_SAMPLES, BackfillPlanner

    planner = BackfillPlanner()
    for index in range(100):
        planner.held.add(index)
    planner.saw_log_window(0, 2**32 - 2)
    rounds = [planner.due(float(t)) for t in range(20)]  # unbounded, each round cut 8.4 M ranges (7.5 s)
    assert sum(b - a for a, b in planner.fetchable()) <= MAX_LOG_SAMPLES
    assert all(len(r) <= 16 for r in rounds) and sum(map(len, rounds)) <= 3 * MAX_LOG_SAMPLES // REQUEST_SAMPLES


def test_a_connection_whose_hellos_are_never_answered_is_given_up_for_a_new_one() -> None:
    """L3: after a reconnect every HELLO answer was lost while other frames came: the session stayed half up (no
    heartbeat, TIMESYNC, backfill) for as long as that lasted. After 5 tries it now takes a new connection."""
    from groundstation.links import make_link
    from groundstation.session.agent_session import Session
    from groundstation.session.core import HELLO_TRIES
    from tests.security.attack import QUICK

    agent = FakeAgent()
    try:
        with Session(make_link(agent.url), QUICK) as session:
            agent.hello_on_accept = False
            agent.unanswered_hellos = HELLO_TRIES  # every HELLO of the next connection (the agent keeps sending)
            agent.disconnect()
            assert wait_for(lambda: not session.link_up, 5)
            assert wait_for(lambda: session.link_up, 15), "the session came back up"
    finally:
        agent.close()
    assert agent.connections == 3  # the first, the reconnect whose HELLOs went unanswered, and a new one
