"""The SAMPLEs an agent sends after the run's end (it goes on sampling while the final backfill runs) are true ones:
recorded raw, never refused as impossible (a scripted agent over real TCP)."""

from __future__ import annotations

import time

from groundstation.links import make_link
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import LinkEvent, Received, Sent
from groundstation.session.exactness import SAMPLE_SLACK
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent


class Samples:
    def __init__(self) -> None:
        self.after_end: list[int] = []
        self.all: list[int] = []

    def on_received(self, received: Received) -> None:
        if isinstance(received.message, m.Sample):
            self.all.append(received.message.sample)
            if received.after_end:
                self.after_end.append(received.message.sample)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


def test_samples_after_the_runs_end_are_handed_on_not_refused_as_impossible() -> None:
    """The fault matrix's 'all at once' counted a few more seq gaps than it could see (446 vs 445): the run's end
    capped the log end the impossible-index check believed, so the SAMPLEs after it were dropped unrecorded once
    SAMPLE_SLACK past the end, though the decoder had counted their seq gaps."""
    agent = FakeAgent(period_s=0.0005)  # fast, so SAMPLE_SLACK samples past the end come within a second or two
    samples = Samples()
    try:
        with Session(make_link(agent.url), SessionConfig(backoff_s=(0.05, 0.2), link_timeout_s=2.0), [samples]) as s:
            s.command(m.StartLearning(max_episodes=0))
            deadline = time.monotonic() + 10
            while len(samples.all) < 50 and time.monotonic() < deadline:
                time.sleep(0.02)
            s.request_backfill(timeout_s=1.0, final=True)
            end = s.backfill.end_limit
            assert end is not None
            while agent.sample < end + SAMPLE_SLACK + 500 and time.monotonic() < deadline + 20:
                time.sleep(0.05)
            time.sleep(0.5)  # the frames in flight
            impossible = s.sample_check.impossible
    finally:
        agent.close()
    assert agent.sample >= end + SAMPLE_SLACK + 500, "the agent sampled far enough past the end"
    assert impossible == 0
    assert max(samples.after_end) >= end + SAMPLE_SLACK + 300
