"""One agent, one owner (issue 25 H4): a second run on an agent a local run holds is refused in one line, and a tool
given that agent's URL attaches to the run's hub instead of taking the agent's one link."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from groundstation.links import make_link
from groundstation.links.runs import attach_url
from groundstation.session.agent_session import Session, SessionConfig
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.security.attack import hub_run


def test_a_second_run_on_a_held_agent_is_refused_in_one_line_and_tools_go_through_the_hub(tmp_path: Path) -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (session, _, info):
            done = subprocess.run([sys.executable, "-m", "groundstation.cli.app", "run", agent.url, "--out",
                                   str(tmp_path)], capture_output=True, text=True, timeout=60)
            assert attach_url(agent.url) == f"hub://{info.run}"
            tool = Session(make_link(attach_url(agent.url)), SessionConfig(reconnect=False, backfill=False))
            with tool:
                tool.command(m.ParamGet(index=-1, name="z_tol_m"))
            assert session.link_up
    finally:
        agent.close()
    lines = [line for line in done.stderr.splitlines() if line.startswith("dive:")]  # (and "connecting to ...")
    assert "Traceback" not in done.stderr
    assert done.returncode == 1 and len(lines) == 1 and f"held by dive run {info.run}" in lines[0], done.stderr
    assert agent.connections == 1  # neither the second run nor the tool took the run's link
    assert not list(tmp_path.glob("*.mcap"))


def test_a_run_whose_link_another_ground_takes_stops_in_one_line_instead_of_fighting(tmp_path: Path) -> None:
    """The agent (the real virtual one) tells the old connection it was replaced (SPEC.md s. 3); the run stops."""
    from groundstation.errors import LinkTakenError
    from groundstation.recording.info import summarize
    from tests.security.attack import RunInThread
    from tests.simulator.agent_client import AgentClient, running
    from tests.waiting import wait_for

    with running("--tcp", "127.0.0.1:0", "--speed", "5", "--seed", "4") as server:
        # a link timeout longer than a loaded machine's stalls: a reconnect of ours would take the link back first
        job = RunInThread(server.address, tmp_path, SessionConfig(backoff_s=(0.05, 0.2), link_timeout_s=6.0))
        assert wait_for(lambda: any(tmp_path.glob("*.mcap")), 120)
        other = AgentClient.tcp(server.address)  # another ground (another machine, say) connects to the agent
        try:
            other.hello()
            job.join(30)  # by itself
        finally:
            other.close()
    assert isinstance(job.error, LinkTakenError), job.error
    assert "taken by another ground" in str(job.error)
    [recording] = tmp_path.glob("*.mcap")
    assert summarize(recording).complete
