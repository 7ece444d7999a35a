"""One agent, many tools: `dive run` is the hub every other `dive` command on the machine attaches to.

Real processes and real TCP: a fake agent with one slot, `dive run` as a child process, and the tools
(`status`, `mark`, `params`, `surface`, `view`) as further child processes, as a user types them.
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from groundstation.recording.info import summarize
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import DIVE, dive, dive_env, one_line_failure, running


@pytest.mark.slow
def test_tools_attach_to_the_running_session_without_taking_the_agents_link(tmp_path: Path) -> None:
    agent = FakeAgent()
    runtime = tmp_path / "runtime"
    try:
        with running(runtime, agent.url, tmp_path / "rec") as run:
            viewer = subprocess.Popen([*DIVE, "view", "--viewer", "none", "--rrd", str(tmp_path / "live.rrd")],
                                      env=dive_env(runtime), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            [announced] = (runtime / "runs").glob("*.json")
            recording = json.loads(announced.read_text())["recording"]
            info = dive(runtime, "log", "info", recording)  # the file the run is still writing
            assert info.returncode == 0 and f"(being recorded by dive run {run.pid})" in info.stdout, info.stderr
            status = dive(runtime, "status")
            assert status.returncode == 0, status.stderr
            assert "agent 'fake' id 000a6e47" in status.stdout and "rtt" in status.stdout
            marked = dive(runtime, "mark", "tapped the tank")
            assert marked.returncode == 0 and f"marked in run {run.pid}" in marked.stdout, marked.stderr
            got = dive(runtime, "params", "get", "z_tol_m")
            assert got.returncode == 0 and "z_tol_m = " in got.stdout, got.stderr
            surfaced = dive(runtime, "surface")
            assert surfaced.returncode == 0 and f"surfacing (hub://{run.pid})" in surfaced.stdout, surfaced.stderr
            negative = dive(runtime, "params", "set", "term_reward", "-5", "--reset-model")  # no `--` needed
            assert negative.returncode == 0 and "term_reward = -5" in negative.stdout, negative.stderr
            time.sleep(1.0)
            viewer.send_signal(signal.SIGINT)
            _, view_err = viewer.communicate(timeout=30)
            assert viewer.returncode == 130, view_err
        _, run_err = run.communicate()
        assert run.returncode == 130, run_err  # stopped by Ctrl-C: the one convention
        assert "took over (CMD_SURFACE from another tool)" in run_err  # the operator's surface stands
    finally:
        agent.close()
    assert agent.connections == 1  # every tool went through the run's one link
    # PARAM_SET: the run's dump_each_episode (dumps after every episode by default) and the tool's term_reward
    assert agent.executed.count("CMD_SURFACE") == 1 and agent.executed.count("PARAM_SET") == 2
    [recording] = sorted((tmp_path / "rec").glob("*.mcap"))
    contents = read_recording(recording, {"/marker", "/ground/CMD_SURFACE", "/ground/PARAM_SET"})
    topics = [m.topic for m in contents.messages]
    assert [m.json()["text"] for m in contents.messages if m.topic == "/marker"] == ["tapped the tank"]
    assert topics.count("/ground/CMD_SURFACE") == 1  # the forwarded command is in the run's recording
    assert summarize(recording).link_losses == 0
    assert (tmp_path / "live.rrd").stat().st_size > 10_000  # the viewer got the telemetry fanned out
    assert not list((runtime / "runs").glob("*.json"))  # the run withdrew its announcement


def test_without_a_run_emergency_commands_fail_in_one_line_and_start_nothing(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    for command in (["surface"], ["hover", "0.5"], ["status"], ["dump"], ["params"]):
        one_line_failure(dive(runtime, *command), "no `dive run` is running on this machine")
    one_line_failure(dive(runtime, "mark", "lost?"), "no `dive run` is running on this machine")


@pytest.mark.slow
def test_mark_reaches_only_the_run_it_names(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    agents = [FakeAgent(), FakeAgent()]
    try:
        with running(runtime, agents[0].url, tmp_path / "a") as first, \
                running(runtime, agents[1].url, tmp_path / "b"):
            one_line_failure(dive(runtime, "mark", "which?"), "2 dive runs are running")
            one_line_failure(dive(runtime, "surface"), "2 dive runs are running")
            named = dive(runtime, "mark", "--run", str(first.pid), "only in a")
            assert named.returncode == 0 and f"marked in run {first.pid}" in named.stdout, named.stderr
            one_line_failure(dive(runtime, "mark", "--run", "999999999", "nowhere"), "no dive run '999999999'")
    finally:
        for agent in agents:
            agent.close()
    markers = {}
    for folder in ("a", "b"):
        [recording] = list((tmp_path / folder).glob("*.mcap"))
        contents = read_recording(recording, {"/marker"})
        markers[folder] = [m.json()["text"] for m in contents.messages]
    assert markers == {"a": ["only in a"], "b": []}


@pytest.mark.parametrize(("command", "why"), [(["hover", "{url}", "-1"], "outside [0, 2.5] m"),
                                             (["params", "{url}", "set", "z_tol_m", "-5"], "outside [0.01, 0.5]")])
def test_negative_values_reach_the_check_not_the_option_parser(tmp_path: Path, command: list[str], why: str) -> None:
    agent = FakeAgent()
    try:
        done = dive(tmp_path, *(part.format(url=agent.url) for part in command))
    finally:
        agent.close()
    one_line_failure(done, why)
