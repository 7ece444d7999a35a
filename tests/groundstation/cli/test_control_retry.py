"""`dive start` whose retry crosses a session start (SPEC.md 1.2 s. 5): one line, "may have run", and the mode."""

from __future__ import annotations

from typer.testing import CliRunner

from groundstation.cli.app import app
from tests.groundstation.fake_agent import FakeAgent


def test_dive_start_says_in_one_line_that_it_may_have_run_and_the_agents_mode() -> None:
    agent = FakeAgent()
    agent.mode_checks = True
    agent.drop_before_ack = "CMD_START"  # it starts learning; the link drops before the ACK
    try:
        done = CliRunner().invoke(app, ["start", agent.url], env={"COLUMNS": "200"})
    finally:
        agent.close()
    lines = done.stdout.strip().splitlines()
    assert done.exit_code == 0, (done.stdout, done.stderr)
    assert len(lines) == 1 and "Traceback" not in done.stdout + done.stderr
    assert lines[0].startswith("CMD_START may have run: the link dropped before its ACK")
    assert "NOT_ALLOWED_IN_MODE; the agent is LEARNING" in lines[0] and agent.url in lines[0]
    assert agent.executed.count("CMD_START") == 2 and agent.connections == 2 and agent.learning
