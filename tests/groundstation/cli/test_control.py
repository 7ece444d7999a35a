"""The operator's controls on a tank day: a real `dive run` on the virtual agent, its hub, and the tools as processes.

Start, pause, go to another depth, resume, an emergency surface, start again: all without restarting the run,
each answered with the agent's ACK and its mode, a refusal saying what to do instead.
"""

from __future__ import annotations

import re
import subprocess
import time
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from tests.groundstation.hub_helpers import (
    DIVE,
    SIM,
    agent_mode,
    dive,
    dive_env,
    one_line_failure,
    running,
    until_mode,
)

pytestmark = pytest.mark.slow
def test_a_tank_day_from_the_command_line_without_restarting_the_run(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    with running(runtime, SIM, tmp_path / "rec", "--success-time", "5", start_timeout_s=120) as run:
        assert until_mode(runtime, {"LEARNING"}) == "LEARNING"
        # hover while learning: refused by the agent, and the line says what to do
        one_line_failure(dive(runtime, "hover", "0.3"), "surface first: dive surface")
        paused = dive(runtime, "pause")
        assert paused.returncode == 0 and "CMD_PAUSE accepted" in paused.stdout, paused.stderr
        assert "the agent is PAUSED" in paused.stdout
        moved = dive(runtime, "target", "0.5")
        assert moved.returncode == 0 and "CMD_SET_TARGET accepted" in moved.stdout, moved.stderr
        resumed = dive(runtime, "resume")
        assert resumed.returncode == 0 and "CMD_START accepted" in resumed.stdout, resumed.stderr
        assert re.search(r"the agent is (RECOVERING|LEARNING)", resumed.stdout), resumed.stdout
        one_line_failure(dive(runtime, "resume"), "not paused: dive start starts learning")
        surfaced = dive(runtime, "surface")
        assert surfaced.returncode == 0 and "surfacing (hub://" in surfaced.stdout, surfaced.stderr
        until_mode(runtime, {"IDLE"})
        time.sleep(1.0)  # the run would have started it again by now if it ignored the operator
        assert agent_mode(runtime) == "IDLE"
        # not on a terminal: reset-model needs --yes, and nothing is sent without it
        one_line_failure(dive(runtime, "reset-model"), "add --yes", code=2)
        reset = dive(runtime, "reset-model", "--yes")
        assert reset.returncode == 0 and "CMD_RESET_MODEL accepted" in reset.stdout, reset.stderr
        assert "the agent is IDLE" in reset.stdout
        started = dive(runtime, "start")
        assert started.returncode == 0 and "CMD_START accepted" in started.stdout, started.stderr
        assert until_mode(runtime, {"LEARNING"}) == "LEARNING"
        time.sleep(3.0)  # an episode or so of the handed-back run
    _, err = run.communicate()
    assert run.returncode == 130, err
    said = err.splitlines()
    assert any("the operator paused learning" in line and "dive resume" in line for line in said), err
    assert any("took over (CMD_SURFACE" in line and "dive start" in line for line in said), err
    assert sum("handed the agent back" in line for line in said) == 2, err  # the resume and the start
    [recording] = sorted((tmp_path / "rec").glob("*.mcap"))
    commands = ["/ground/CMD_PAUSE", "/ground/CMD_SET_TARGET", "/ground/CMD_START", "/ground/CMD_SURFACE",
                "/ground/CMD_HOVER", "/ground/CMD_RESET_MODEL"]
    contents = read_recording(recording, {*commands, "/agent/EPISODE_END"})
    topics = [m.topic for m in contents.messages]
    assert topics.count("/ground/CMD_START") == 3  # the run's own, the resume and the start
    assert topics.count("/ground/CMD_RESET_MODEL") == 1  # only the one with --yes reached the agent
    last_start = max(i for i, topic in enumerate(topics) if topic == "/ground/CMD_START")
    assert "/agent/EPISODE_END" in topics[last_start:]  # the handed-back run learns and records on
    assert [m.json()["target_depth_m"] for m in contents.messages if m.topic == "/ground/CMD_SET_TARGET"] == \
        [pytest.approx(0.5)]


def test_a_depth_out_of_range_is_refused_before_anything_is_sent(tmp_path: Path) -> None:
    done = subprocess.run([*DIVE, "target", "7"], env=dive_env(tmp_path), capture_output=True, text=True, timeout=30)
    one_line_failure(done, "target depth 7 m is outside [0.05, 2.5] m")
