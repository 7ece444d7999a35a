"""The unchanged ground station against the C firmware's host build (`dive sim --firmware c`), over real TCP,
a real pseudo-terminal and sim:// : HELLO answered, status, parameters, a recorded learning run."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.recording.info import summarize
from groundstation.recording.recorder import RecorderConfig
from groundstation.run.job import RunConfig, run
from protocol.parameters import PARAM_COUNT
from tests.firmware.core_build import c_agent, use_firmware_cache

pytestmark = pytest.mark.slow
FAST = {"success_time_s": "5"}  # short episodes keep the suite quick


@pytest.fixture(scope="module")
def firmware_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return use_firmware_cache(tmp_path_factory)


@pytest.fixture(scope="module")
def tcp_agent(firmware_cache: Path) -> Iterator[str]:
    """One agent for the TCP tests (status and params first, then a run on the same agent)."""
    with c_agent("--tcp", "127.0.0.1:0", seed=7) as address:
        assert address.startswith("tcp://127.0.0.1:"), address
        yield address


@pytest.fixture
def pty_agent(firmware_cache: Path) -> Iterator[str]:
    with c_agent("--pty", seed=7) as device:
        assert device.startswith("/dev/"), device
        yield f"serial://{device}?baud=115200"


def test_status_and_params_over_tcp(tcp_agent: str) -> None:
    status = CliRunner().invoke(app, ["status", tcp_agent])
    assert status.exit_code == 0, status.output
    assert "firmware 1.1.0" in status.stdout and f"{PARAM_COUNT} parameters" in status.stdout
    assert "mode IDLE" in status.stdout
    params = CliRunner().invoke(app, ["params", tcp_agent])
    assert params.exit_code == 0, params.output
    lines = [line for line in params.stdout.splitlines() if line.strip()]
    assert len(lines) == PARAM_COUNT
    # The real agent reports the simulator-only parameter with minimum = maximum = 0.
    assert any("start_at_rest" in line and "[0 .. 0]" in line for line in lines)


def test_dive_run_over_tcp_records_a_complete_session(tcp_agent: str, tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["run", tcp_agent, "--episodes", "2", "--success-time", "5", "--viewer", "none",
                                      "--out", str(tmp_path)])
    assert result.exit_code == 0, result.output
    summary = summarize(Path(result.stdout.strip().splitlines()[-1]))
    assert summary.complete and len(summary.episodes) >= 2 and summary.samples_missing == 0


def test_dive_run_over_a_pty(pty_agent: str, tmp_path: Path) -> None:
    result = run(RunConfig(url=pty_agent, episodes=2, params=FAST, recorder=RecorderConfig(directory=tmp_path)))
    summary = summarize(result.paths[0])
    assert summary.complete and len(summary.episodes) >= 2 and summary.samples_missing == 0


# dive check groups that finish quickly at full speed; the command x mode matrix and link loss need an agent slower
# than full speed to meet LEARNING (`dive check "sim://?speed=5&firmware=c" --key-file K` runs everything).
QUICK_CHECKS = ("handshake", "seq", "junk", "timesync", "ack", "counters", "signing", "dump", "log", "params.list",
                "params.get", "params.set", "params.refused", "params.ram_budget")


def test_dive_check_passes_against_the_host_build(firmware_cache: Path, tmp_path: Path) -> None:
    key_file = tmp_path / "agent.key"
    key_file.write_text(os.urandom(32).hex() + "\n")
    key_file.chmod(0o600)
    url = f"sim://?speed=max&firmware=c&seed=4&key_file={key_file}&state_dir={tmp_path / 'state'}"
    only = [arg for name in QUICK_CHECKS for arg in ("--only", name)]
    result = CliRunner().invoke(app, ["check", url, "--key-file", str(key_file), *only], env={"COLUMNS": "200"})
    assert result.exit_code == 0, result.output
    assert "conforms" in result.stdout and " 0 failed" in result.stdout


def test_missing_compiler_is_one_clear_line(tmp_path: Path) -> None:
    env = {**os.environ, "CC": "no-such-cc", "DIVE_FIRMWARE_CACHE": str(tmp_path)}
    env.pop("DIVE_FIRMWARE_LIB", None)
    result = subprocess.run([sys.executable, "-m", "simulator", "serve", "--firmware", "c", "--tcp", "127.0.0.1:0"],
                            capture_output=True, text=True, env=env, timeout=120, check=False)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == [
        "python -m simulator: cannot build the C firmware: 'no-such-cc' not found (install make and a C compiler)"]
