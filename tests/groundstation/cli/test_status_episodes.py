"""`dive status` through a running run's hub says what is known of the episodes, never `- ok`: the successes and the
last episode from the run's episode table when one has ended, "no episode ended yet" when none has."""

from __future__ import annotations

import os
import threading
from pathlib import Path

import pytest

from groundstation.links import make_link
from groundstation.links.hub_auth import new_token
from groundstation.links.runs import RunInfo, announce
from groundstation.run.history import History
from groundstation.run.hub import Hub
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.status_line import AgentStatus, successes_text
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import dive


def test_status_through_the_hub_names_the_last_episode_the_run_saw_end(tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    runtime = tmp_path / "runtime"
    monkeypatch.setenv("DIVE_RUNTIME_DIR", str(runtime))
    agent = FakeAgent(episode_len=20)
    ended = threading.Event()
    try:
        # The run's side as run/job.py wires it: a session, its history, and the hub serving both.
        session = Session(make_link(agent.url), SessionConfig(reconnect=False))
        history = History()
        session.add_listener(history)
        session.add_listener(session.rx_listener(
            lambda received: ended.set() if isinstance(received.message, m.EpisodeEnd) else None))
        with session:
            token = new_token()
            hub = Hub(session, token).start()
            hub.history = history
            session.add_listener(hub)
            try:
                announce(RunInfo(str(os.getpid()), os.getpid(), hub.address, agent.url, "", 0.0, token=token))
                agent.max_episodes, agent.learning = 1, True  # one episode (a success), then IDLE
                assert ended.wait(10.0)
                status = dive(runtime, "status")  # no episode ends while it watches: the run's table tells
            finally:
                hub.close()
    finally:
        agent.close()
    assert status.returncode == 0, status.stderr
    assert "last episode ended: 1 (success, 2.0 s in the region)" in status.stdout, status.stdout
    assert "| episode 1 | 1 ok |" in status.stdout and "- ok" not in status.stdout, status.stdout




@pytest.mark.parametrize(("agent", "text"), [
    (AgentStatus(episode=4, successes=2), "2 ok"),
    (AgentStatus(episode=0), "no episode ended yet"),  # nothing has started
    (AgentStatus(episode=4, ends_known=True), "no episode ended yet"),  # the run's table has no EPISODE_END
    (AgentStatus(episode=4), "successes unknown (no episode ended while watching)"),  # straight to the agent
])
def test_the_successes_say_what_is_known(agent: AgentStatus, text: str) -> None:
    assert successes_text(agent) == text
