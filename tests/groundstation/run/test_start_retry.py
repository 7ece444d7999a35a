"""`dive run` whose CMD_START retry crosses a reconnect (SPEC.md 1.2 s. 5): the first try ran, so the run goes on."""

from __future__ import annotations

from pathlib import Path

from typer.testing import CliRunner

from groundstation.cli.app import app
from tests.groundstation.fake_agent import FakeAgent


def test_a_start_that_may_have_run_and_left_the_agent_learning_is_not_an_error(tmp_path: Path) -> None:
    agent = FakeAgent(episode_len=300)  # 1.5 s: still learning when the retry comes
    agent.mode_checks = True
    agent.drop_before_ack = "CMD_START"  # it starts learning; the link drops before the ACK; the retry is refused
    try:
        done = CliRunner().invoke(app, ["run", agent.url, "--episodes", "1", "--out", str(tmp_path)],
                                  env={"COLUMNS": "200", "XDG_RUNTIME_DIR": str(tmp_path / "runtime")})
    finally:
        agent.close()
    output = done.stdout + done.stderr
    assert done.exit_code == 0, output
    assert "CMD_START's first try ran (its retry crossed a reconnect): the agent is LEARNING" in output
    assert agent.executed.count("CMD_START") == 2 and agent.connections == 2
    assert list(tmp_path.glob("*.mcap")), output
