"""The session against a scripted agent over real TCP: HELLO checks, commands, params, dumps, reconnect."""

from __future__ import annotations

import time

import pytest

from groundstation.errors import CommandError, CommandMayHaveRun, IncompatibleAgentError, LinkError, ParameterError
from groundstation.links import make_link
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.clock import ClockModel
from groundstation.session.dumps import KEPT_DUMPS
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from groundstation.session.gaps import SampleRanges
from groundstation.session.params import cache_path
from protocol import DumpKind
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent


class Collect:
    def __init__(self) -> None:
        self.received: list[Received] = []
        self.sent: list[Sent] = []
        self.events: list[LinkEvent] = []

    def on_received(self, received: Received) -> None:
        self.received.append(received)

    def on_sent(self, sent: Sent) -> None:
        self.sent.append(sent)

    def on_event(self, event: LinkEvent) -> None:
        self.events.append(event)


def test_connect_fetches_and_caches_the_parameter_table(fake_agent: FakeAgent) -> None:
    with Session(make_link(fake_agent.url)) as s:
        assert s.agent_hello is not None and s.agent_hello.name == "fake"
        assert [p.name for p in s.params][:2] == ["target_depth_m", "z_tol_m"]
        applied = s.set_param("target_depth_m", "0.8")
        assert applied.value == pytest.approx(0.8)
        with pytest.raises(ParameterError, match=r"outside \[0.05, 2\]"):
            s.set_param("target_depth_m", 9)
        with pytest.raises(ParameterError, match="unknown parameter 'nope'"):
            s.set_param("nope", 1)
        path = cache_path(s.agent_hello.definitions_hash, s.agent_hello.node_id)
    assert "target_depth_m" in path.read_text()


@pytest.mark.parametrize(("version", "hash_", "pattern"), [
    (2, None, "protocol version 2, this ground station speaks version 1"),
    (1, 0xDEADBEEF, "hash deadbeef, firmware 9.8.7.*differs from ours"),
])
def test_incompatible_agent_is_one_clear_error(version: int, hash_: int | None, pattern: str) -> None:
    agent = FakeAgent(protocol_version=version, defs_hash=hash_)
    try:
        with pytest.raises(IncompatibleAgentError, match=pattern):
            Session(make_link(agent.url)).connect()
    finally:
        agent.close()


def test_lost_ack_is_retried_with_the_same_seq_and_executed_once(fake_agent: FakeAgent) -> None:
    collect = Collect()
    with Session(make_link(fake_agent.url), listeners=[collect]) as s:
        fake_agent.ignore_commands = 1
        s.command(m.Surface())
        surfaces = [x for x in collect.sent if isinstance(x.message, m.Surface)]
        assert len(surfaces) == 2 and surfaces[0].seq == surfaces[1].seq and surfaces[0].wire == surfaces[1].wire
        assert fake_agent.executed.count("CMD_SURFACE") == 1
        assert s.stats.snapshot(s.decoder.stats)["retries"] == 1


def test_a_command_sent_while_the_link_is_down_is_delivered_after_the_reconnect(fake_agent: FakeAgent) -> None:
    with Session(make_link(fake_agent.url), SessionConfig(backoff_s=(0.05, 0.2), fetch_params=False)) as s:
        fake_agent.disconnect()
        deadline = time.monotonic() + 5
        while s.link_up and time.monotonic() < deadline:  # the reader has seen the loss
            time.sleep(0.01)
        assert not s.link_up
        s.command(m.Surface(), timeout_s=10)
        assert fake_agent.executed.count("CMD_SURFACE") == 1
        assert s.stats.reconnects >= 1


def test_without_reconnect_a_command_on_a_lost_link_is_a_link_error(fake_agent: FakeAgent) -> None:
    with Session(make_link(fake_agent.url), SessionConfig(reconnect=False, fetch_params=False)) as s:
        fake_agent.disconnect()
        deadline = time.monotonic() + 5
        while s.link_up and time.monotonic() < deadline:
            time.sleep(0.01)
        with pytest.raises(LinkError):
            s.command(m.Surface(), timeout_s=2)


def test_nack_is_a_command_error_naming_the_reason(fake_agent: FakeAgent) -> None:
    with Session(make_link(fake_agent.url), SessionConfig(fetch_params=False)) as s:
        with pytest.raises(CommandError, match="PARAM_GET refused by the agent: BAD_VALUE"):
            s.command(m.ParamGet(index=-1, name="missing"))


def test_dump_missing_chunks_are_requested_again(fake_agent: FakeAgent) -> None:
    with Session(make_link(fake_agent.url)) as s:
        dump = s.dump(DumpKind.VALUES)
    assert dump.values() == [float(i) for i in range(101)]
    assert fake_agent.executed.count("CMD_DUMP") == 2  # the snapshot, then its missing range


def test_a_long_session_keeps_only_the_newest_dumps(fake_agent: FakeAgent) -> None:
    with Session(make_link(fake_agent.url)) as s:
        for _ in range(KEPT_DUMPS + 4):
            assert s.dump(DumpKind.VALUES).values() == [float(i) for i in range(101)]
        assert s.dumps.held == KEPT_DUMPS  # memory bounded whatever the session's length
        assert s.dumps.tracked <= KEPT_DUMPS


def test_reconnect_backfills_every_missed_sample(fake_agent: FakeAgent) -> None:
    collect = Collect()
    fake_agent.drop_every = 7
    with Session(make_link(fake_agent.url), SessionConfig(backoff_s=(0.05, 0.2)), [collect]) as s:
        s.command(m.StartLearning(max_episodes=12))
        time.sleep(0.4)
        fake_agent.disconnect()
        deadline = time.monotonic() + 10
        while fake_agent.learning and time.monotonic() < deadline:
            time.sleep(0.05)
        assert s.request_backfill(8.0) == 0
        assert s.link_up
    kinds = [e.kind for e in collect.events]
    assert EventKind.LINK_LOST in kinds and EventKind.LINK_RESTORED in kinds
    samples = [r for r in collect.received if isinstance(r.message, m.Sample)]
    indices = sorted(r.message.sample for r in samples)  # type: ignore[attr-defined]
    assert indices == list(range(fake_agent.sample))
    assert any(r.backfilled for r in samples)
    ends = {r.message.episode for r in collect.received if isinstance(r.message, m.EpisodeEnd)}  # type: ignore
    assert ends == set(range(1, 13))


def test_clock_model_recovers_offset_and_drift() -> None:
    clock = ClockModel()
    offset_us, drift = 5_000_000.0, 50e-6
    for i in range(20):
        t1 = 1_000_000_000 + i * 1_000_000
        t2 = int(t1 + 300 + offset_us + drift * (t1 - 1_000_000_000))
        clock.add(t1, t2, t2 + 10, t1 + 610 + (i % 3) * 200)
    assert clock.drift == pytest.approx(drift, rel=0.05)
    agent_us = int(1_019_000_000 + offset_us + drift * 19_000_000)
    host_ns = clock.to_host_ns(agent_us)
    assert host_ns is not None and abs(host_ns / 1000 - 1_019_000_000) < 200


def test_sample_ranges_report_exact_gaps() -> None:
    r = SampleRanges()
    for i in [*range(0, 10), *range(12, 20), 25, 11]:
        r.add(i)
    assert not r.add(5)
    assert r.missing() == [(10, 11), (20, 25)]
    assert len(r) == 20 and 11 in r and 21 not in r


def test_a_retry_across_a_session_start_refused_in_mode_is_reported_as_may_have_run(fake_agent: FakeAgent) -> None:
    """SPEC.md 1.2 s. 5: CMD_START ran, the link dropped before its ACK; the retry after the reconnect meets an
    emptied ACK memory and is NOT_ALLOWED_IN_MODE because the first moved the agent: "may have run", with the mode."""
    fake_agent.mode_checks = True
    with Session(make_link(fake_agent.url), SessionConfig(backoff_s=(0.05, 0.2), fetch_params=False)) as s:
        fake_agent.drop_before_ack = "CMD_START"
        with pytest.raises(CommandMayHaveRun, match=r"CMD_START may have run: .*NOT_ALLOWED_IN_MODE; "
                                                    r"the agent is LEARNING") as caught:
            s.command(m.StartLearning(max_episodes=0), timeout_s=10)
        assert caught.value.mode == "LEARNING"
        assert fake_agent.executed.count("CMD_START") == 2 and fake_agent.connections == 2
        # without a session start in between, the same NACK is a plain refusal
        with pytest.raises(CommandError, match="CMD_START refused by the agent: NOT_ALLOWED_IN_MODE") as plain:
            s.command(m.StartLearning(max_episodes=0))
        assert not isinstance(plain.value, CommandMayHaveRun)
