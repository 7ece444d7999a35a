"""The view that does not mislead (issue 27 item 5), with real processes: a run without a viewer records its dumps;
one SIGTERM ends a run serving the web viewer; every busy port given is named in one line; the --viewer help says
each command's own default."""

from __future__ import annotations

import re
import signal
import socket
import subprocess
import time
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.cli.validate import free_port
from groundstation.mcap_io import read_recording
from tests.groundstation.hub_helpers import DIVE, dive_env, hub_announced


@pytest.mark.slow
def test_a_run_without_a_viewer_records_values_and_policy_after_every_episode(tmp_path: Path) -> None:
    done = subprocess.run([*DIVE, "run", "sim://?speed=max&seed=3", "--episodes", "3", "--success-time", "5",
                           "--out", str(tmp_path)], env=dive_env(tmp_path / "runtime"), capture_output=True, text=True,
                          timeout=180)
    assert done.returncode == 0, done.stderr
    [recording] = sorted(tmp_path.glob("*.mcap"))
    contents = read_recording(recording, {"/dump/VALUES", "/dump/POLICY", "/agent/EPISODE_END"})
    topics = [m.topic for m in contents.messages]
    assert topics.count("/agent/EPISODE_END") >= 3
    assert topics.count("/dump/VALUES") >= 3 and topics.count("/dump/POLICY") >= 3  # one of each per episode


@pytest.mark.slow
def test_one_sigterm_ends_a_run_serving_the_web_viewer(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    run = subprocess.Popen([*DIVE, "run", "sim://?speed=20&seed=3", "--success-time", "5", "--viewer", "web",
                            "--web-port", str(free_port()), "--grpc-port", str(free_port()), "--out", str(tmp_path)],
                           env=dive_env(runtime), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 120
        while time.monotonic() < deadline and run.poll() is None and not hub_announced(runtime):
            time.sleep(0.1)
        time.sleep(1.0)
        run.send_signal(signal.SIGTERM)  # once
        out, err = run.communicate(timeout=60)
    finally:
        if run.poll() is None:
            run.kill()
            run.wait()
    assert run.returncode == 130, err
    # what the run left the agent doing, then that the recording is whole
    assert re.search(r"stopped by SIGTERM; the agent was \w+ at \d\.\d\d m: CMD_STOP accepted, [^;]+; the recording "
                     r"is complete", err), err
    assert out.strip().endswith(".mcap")


def test_every_busy_port_given_is_named_in_one_line() -> None:
    with socket.socket() as web, socket.socket() as grpc:
        for busy in (web, grpc):
            busy.bind(("0.0.0.0", 0))
            busy.listen()
        web_port, grpc_port = web.getsockname()[1], grpc.getsockname()[1]
        done = CliRunner().invoke(app, ["run", "--viewer", "web", "--web-port", str(web_port), "--grpc-port",
                                        str(grpc_port)])
    assert done.exit_code == 2, done.output
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, lines
    assert f"port {web_port} is in use" in lines[0] and f"port {grpc_port} is in use" in lines[0]


def test_the_viewer_help_says_each_commands_own_default() -> None:
    run_help = CliRunner().invoke(app, ["run", "--help"], env={"COLUMNS": "300"}).stdout
    view_help = CliRunner().invoke(app, ["view", "--help"], env={"COLUMNS": "300"}).stdout
    assert "else none (--viewer web on a headless machine)" in " ".join(run_help.split())
    assert "else web; none when --rrd is given" in " ".join(view_help.split())
