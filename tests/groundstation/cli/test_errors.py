"""Every bad input gives one clear line on stderr and a non-zero exit code, never a traceback."""

from __future__ import annotations

import socket
import subprocess
import sys
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from tests.groundstation.fake_agent import FakeAgent
from tests.reliability.recordings import DIVE_MAIN, ROOT


def _refused_url() -> str:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return f"tcp://127.0.0.1:{s.getsockname()[1]}"


def _fails_with_one_line(args: list[str], pattern: str) -> None:
    result = CliRunner().invoke(app, args)
    assert result.exit_code != 0
    assert "Traceback" not in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert pattern in lines[0], lines[0]


def test_unreachable_url() -> None:
    url = _refused_url()
    _fails_with_one_line(["status", url], f"{url}: cannot connect")


def test_unknown_scheme() -> None:
    _fails_with_one_line(["status", "udp://1.2.3.4:5"], "unknown link URL 'udp://1.2.3.4:5'")


def test_wrong_protocol_version() -> None:
    agent = FakeAgent(protocol_version=2)
    try:
        _fails_with_one_line(["status", agent.url], "protocol version 2, this ground station speaks version 1")
    finally:
        agent.close()


def test_bad_parameter(fake_agent: FakeAgent) -> None:
    _fails_with_one_line(["params", fake_agent.url, "set", "target_depth_m", "99"], "outside [0.05, 2]")
    _fails_with_one_line(["params", fake_agent.url, "get", "nope"], "unknown parameter 'nope'")
    _fails_with_one_line(["params", fake_agent.url, "get", "z_tol"], "did you mean z_tol_m")  # as set does


def test_params_list_get_set_and_commands(fake_agent: FakeAgent) -> None:
    runner = CliRunner()
    listing = runner.invoke(app, ["params", fake_agent.url])
    assert listing.exit_code == 0 and "target_depth_m" in listing.stdout
    changed = runner.invoke(app, ["params", fake_agent.url, "set", "z_tol_m", "0.2", "--reset-model"])
    assert "z_tol_m = 0.2" in changed.stdout
    assert runner.invoke(app, ["surface", fake_agent.url]).exit_code == 0
    assert runner.invoke(app, ["hover", fake_agent.url, "0.5"]).exit_code == 0
    dumped = runner.invoke(app, ["dump", fake_agent.url, "--kind", "values"])
    assert dumped.exit_code == 0 and '"kind": "values"' in dumped.stdout
    assert "agent 'fake'" in runner.invoke(app, ["status", fake_agent.url]).stdout
    assert fake_agent.executed.count("CMD_HOVER") == 1


@pytest.mark.parametrize("command", [["log", "info"], ["log", "export"], ["log", "recover"]])
def test_missing_file(tmp_path: Path, command: list[str]) -> None:
    _fails_with_one_line([*command, str(tmp_path / "none.mcap")], "no such recording")


def test_not_an_mcap_file(tmp_path: Path) -> None:
    junk = tmp_path / "junk.mcap"
    junk.write_bytes(b"this is not mcap at all" * 10)
    _fails_with_one_line(["log", "info", str(junk)], "is not an MCAP recording")


def test_speed_with_a_real_agent_url_is_refused() -> None:
    result = CliRunner().invoke(app, ["run", "tcp://10.0.0.1:23", "--speed", "5"])
    assert result.exit_code == 2 and "sim://" in result.output and "Traceback" not in result.output


@pytest.mark.parametrize("args", [["sim", "--tcp", "127.0.0.1:99999"], ["study", "--trials", "0"],
                                  ["fit", "--window", "0", "any.mcap"]], ids=["sim", "study", "fit"])
def test_sim_and_study_say_a_bad_argument_as_every_dive_command_does(args: list[str]) -> None:
    """`dive sim` and `dive study` run the simulator's own command line in a child process: its one line is named
    after `dive` too, not after the child."""
    done = subprocess.run([sys.executable, "-c", DIVE_MAIN, *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=120, check=False)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dive: "), done.stderr
