"""Issue 13 against a scripted agent over real TCP: bounded dumps, exact recordings, backfill that does not give up,
a HELLO lost on a reconnect, another agent at the same address. Each test failed before the fix it names."""

from __future__ import annotations

import json
import resource
import threading
import time
from pathlib import Path

import pytest

from groundstation.errors import AgentChangedError
from groundstation.links import make_link
from groundstation.mcap_io import iter_messages
from groundstation.recording.info import summarize
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.run.job import RunConfig, run
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import DumpKind, Message, Mode
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.waiting import wait_for

QUICK = SessionConfig(backoff_s=(0.05, 0.2), link_timeout_s=1.0)


class Events:
    def __init__(self) -> None:
        self.events: list[LinkEvent] = []
        self.samples: list[int] = []

    def on_received(self, received: Received) -> None:
        if isinstance(received.message, m.Sample):
            self.samples.append(received.message.sample)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        self.events.append(event)


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def test_a_dump_announcing_256_mib_allocates_nothing(fake_agent: FakeAgent) -> None:
    """Item 1: dumps.py allocated total_bytes up front (0.5 GB per chunk seen); now bounded by the agent's grid."""
    with Session(make_link(fake_agent.url), QUICK) as s:
        before = rss_mb()
        for dump_id in range(100, 140):  # forty snapshots, each claiming 256 MiB
            fake_agent.send(m.DumpChunk(dump_id=dump_id, kind=int(DumpKind.COUNTS), episode=1,
                                        total_bytes=256 << 20, offset=0, data=bytes(200)))
        assert wait_for(lambda: s.dumps.assembler.refused == 40)
        assert s.dumps.assembler.pending() == {} and s.dumps.tracked == 0
        assert rss_mb() - before < 64
        # a real snapshot of the size the grid allows still completes
        assert len(s.dump(DumpKind.VALUES).data) == 404


def test_a_frame_received_twice_is_recorded_once(fake_agent: FakeAgent, tmp_path: Path) -> None:
    """Item 5: every live frame sent twice, byte for byte (a bridge repeating): each SAMPLE once in the MCAP."""
    fake_agent.duplicate_frames = True
    recorder = Recorder(RecorderConfig(directory=tmp_path))
    events = Events()
    with Session(make_link(fake_agent.url), QUICK, [recorder, events]) as s:
        s.command(m.StartLearning(max_episodes=3))
        assert wait_for(lambda: len(set(events.samples)) >= 60)
        s.command(m.Stop())
        s.request_backfill(3.0)
    recorder.close()
    assert len(events.samples) == len(set(events.samples))
    summary = summarize(recorder.paths[0])
    assert summary.topics["/agent/SAMPLE"] == summary.samples >= 60
    assert summary.samples_missing == 0


def test_an_impossible_sample_index_opens_no_gap(fake_agent: FakeAgent, tmp_path: Path) -> None:
    """Item 5: a SAMPLE at index 2**31 (log_next_sample is ~100) made 2 billion samples 'missing' and asked for them."""
    recorder = Recorder(RecorderConfig(directory=tmp_path))
    events = Events()
    with Session(make_link(fake_agent.url), QUICK, [recorder, events]) as s:
        s.command(m.StartLearning(max_episodes=0))
        assert wait_for(lambda: s.last_heartbeat is not None and s.last_heartbeat.log_next_sample > 20)
        fake_agent.send(m.Sample(t_us=fake_agent.now_us(), sample=2**31, episode=1, step=1, pressure_pa=106000.0,
                                 depth_m=0.5, velocity_mps=0.0, actuator_deg=65.0, actuator_cmd_deg=65.0, reward=-1.0,
                                 state=50, action=0, mode=int(Mode.LEARNING)))
        assert wait_for(lambda: s.sample_check.impossible == 1)
        time.sleep(0.3)
        s.command(m.Stop())
        assert s.request_backfill(3.0) == 0
    assert s.backfill.held.end is not None and s.backfill.held.end < 10_000
    recorder.close()
    assert 2**31 not in events.samples
    assert any(e.kind == EventKind.ERROR and "cannot be true" in e.detail for e in events.events)
    assert summarize(recorder.paths[0]).samples_missing == 0


def test_backfill_keeps_asking_while_the_agent_holds_the_samples(fake_agent: FakeAgent, tmp_path: Path) -> None:
    """Item 4: each range was asked 5 times, then never again; here the first 8 replays are lost, then it comes."""
    fake_agent.drop_every = 7  # every 7th live SAMPLE lost (it stays in the on-board log)
    fake_agent.ignored_log_requests = 8
    config = SessionConfig(backoff_s=(0.05, 0.2), link_timeout_s=1.0, backfill_retry_s=(0.2, 0.5))
    with Session(make_link(fake_agent.url), config) as s:
        s.command(m.StartLearning(max_episodes=4))
        assert wait_for(lambda: fake_agent.episode >= 4 and not fake_agent.learning)
        missing = s.request_backfill(timeout_s=6.0, limit_s=20.0)
    lost, held = s.backfill_status()
    assert fake_agent.log_requests > 8
    assert (missing, lost, held) == (0, 0, 0)


def test_a_long_gap_is_fetched_512_samples_a_request(fake_agent: FakeAgent) -> None:
    """Item 4: the agent replays at most 512 samples per LOG_REQUEST; the ground asks for the rest."""
    fake_agent.episode_len = 1000
    fake_agent.period_s = 0.001
    with Session(make_link(fake_agent.url), QUICK) as s:
        s.command(m.StartLearning(max_episodes=3))
        assert wait_for(lambda: s.samples_held > 10)
        fake_agent.live = False  # a blackout: the rest of the run only in the on-board log
        assert wait_for(lambda: fake_agent.sample > 1600, 30)
        fake_agent.live = True
        assert wait_for(lambda: fake_agent.episode >= 3 and not fake_agent.learning, 30)
        assert s.request_backfill(timeout_s=5.0) == 0
    assert len(s.backfill.held) == fake_agent.sample
    assert fake_agent.sample > 1500 and fake_agent.log_requests >= 3


def test_a_hello_lost_on_the_reconnect_is_sent_again(fake_agent: FakeAgent) -> None:
    """Item 4: the ground sent HELLO once after a reconnect; an agent that only answers HELLOs and lost that one left
    the session half up (no heartbeat, TIMESYNC, backfill) until the link timed out, again and again."""
    with Session(make_link(fake_agent.url), QUICK) as s:
        fake_agent.hello_on_accept = False
        fake_agent.unanswered_hellos = 1
        fake_agent.disconnect()
        assert wait_for(lambda: not s.link_up, 5)
        assert wait_for(lambda: s.link_up, 5), "the session came back up"
        assert fake_agent.unanswered_hellos == 0


def test_another_agent_at_the_same_address_stops_the_run(fake_agent: FakeAgent, tmp_path: Path) -> None:
    """Item 6: after a reconnect a HELLO with another node id was taken for a reboot of ours and recorded on."""
    events = Events()
    config = RunConfig(url=fake_agent.url, episodes=50, recorder=RecorderConfig(directory=tmp_path), session=QUICK)

    def swap() -> None:
        assert wait_for(lambda: fake_agent.episode >= 1)
        fake_agent.node_id, fake_agent.name, fake_agent.boot_id = 0xB0B, "stranger", 99
        fake_agent.disconnect()

    swapper = threading.Thread(target=swap)
    swapper.start()
    started = time.monotonic()
    with pytest.raises(AgentChangedError, match=r"another agent answered after the reconnect \(id 00000b0b"):
        run(config, listeners=[events])
    swapper.join()
    assert time.monotonic() - started < 20
    summary_path = next(tmp_path.glob("*.mcap"))
    summary = summarize(summary_path)
    assert summary.complete and summary.agent["name"] == "fake"
    hellos = [json.loads(x.data) for x in iter_messages(summary_path, {"/agent/HELLO"})]
    assert hellos and {h["node_id"] for h in hellos} == {0xA6E47}  # nothing of the stranger recorded


def test_reordered_frames_are_not_counted_as_lost(fake_agent: FakeAgent) -> None:
    """Item 5: a frame overtaken by the next one was counted lost (and the late one a duplicate)."""
    with Session(make_link(fake_agent.url), QUICK) as s:
        before = s.decoder.stats.lost
        texts: list[Message] = [m.Text(t_us=fake_agent.now_us(), severity=1, text=f"t{i}") for i in range(6)]
        fake_agent.send_reordered(texts, [0, 2, 1, 4, 5, 3])
        assert wait_for(lambda: s.decoder.stats.frames >= 6)
        time.sleep(0.2)
        assert s.decoder.stats.lost == before
        assert s.decoder.stats.duplicates == 0
