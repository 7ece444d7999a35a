"""Status and alarms (issue 27 item 3): a real virtual agent (`python -m simulator serve`), a real `dive run` on it,
the agent frozen with SIGSTOP; the alarms printed and recorded as events in the MCAP file (read back with mcap)."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from tests.groundstation.hub_helpers import DIVE, dive, dive_env, hub_announced

pytestmark = pytest.mark.slow


def _alarm_events(path: Path) -> list[dict[str, object]]:
    with path.open("rb") as f:
        events = [json.loads(message.data) for _, _, message in make_reader(f).iter_messages(topics=["/event"])]
    return [e for e in events if e["kind"] == "alarm"]


def test_alarms_are_printed_recorded_and_status_shows_the_block(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    agent = subprocess.Popen([sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--speed", "20",
                              "--seed", "6"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    run: subprocess.Popen[str] | None = None
    try:
        assert agent.stdout is not None
        url = agent.stdout.readline().strip()
        assert url.startswith("tcp://"), agent.stderr.read() if agent.stderr else ""
        # low_batt_v 4.15: the battery (4.2 V full) is within 0.1 V of it at once, and the agent still dives;
        # max_dive_s 20: 18 s of agent time after it leaves the surface; a depth limit the target passes
        run = subprocess.Popen([*DIVE, "run", url, "--out", str(tmp_path / "rec"), "--success-time", "5",
                                "--param", "low_batt_v=4.15", "--param", "max_dive_s=20", "--alarm-depth", "0.3",
                                "--alarm-link-lost", "1"], env=dive_env(runtime), stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and not hub_announced(runtime):
            time.sleep(0.1)
        time.sleep(3.0)  # 60 s of agent time: it dives past 0.3 m and for 18 s
        status = dive(runtime, "status")
        assert status.returncode == 0, status.stderr
        printed = status.stdout
        assert "status: " in printed and "| depth " in printed and " V | rtt" in printed, printed
        agent.send_signal(signal.SIGSTOP)  # the agent stops sending: silent at 1 s, the link lost at 3 s + 1 s
        time.sleep(6.0)
        agent.send_signal(signal.SIGCONT)
        time.sleep(2.0)
        run.send_signal(signal.SIGINT)
        _, err = run.communicate(timeout=60)
    finally:
        if run is not None and run.poll() is None:
            run.kill()
        agent.send_signal(signal.SIGCONT)
        agent.terminate()
        agent.wait(10)
    assert run.returncode == 130, err
    printed = [line.removeprefix("ALARM: ") for line in err.splitlines() if line.startswith("ALARM: ")]
    for expected in ("battery low", "is past the 0.3 m limit", "(max_dive_s)", "the agent stopped sending",
                     "link lost for more than 1 s"):
        assert any(expected in line for line in printed), (expected, err)
    assert any(line.startswith("status: ") for line in err.splitlines())  # not a terminal: plain status lines
    [recording] = sorted((tmp_path / "rec").glob("*.mcap"))
    recorded = _alarm_events(recording)
    assert {e["data"]["alarm"] for e in recorded} >= {"battery", "depth", "dive_time", "silent", "link_lost"}  # type: ignore[index]
    assert sorted(str(e["detail"]) for e in recorded) == sorted(printed)  # each said is recorded, and only those


def test_on_a_terminal_the_status_line_stays_live_under_the_episode_lines(tmp_path: Path) -> None:
    import os
    import pty

    primary, secondary = pty.openpty()
    env = {**dive_env(tmp_path / "runtime"), "TERM": "xterm-256color"}
    run = subprocess.Popen([*DIVE, "run", "sim://?speed=20&seed=2", "--episodes", "2", "--success-time", "5",
                            "--out", str(tmp_path / "rec")], env=env, stdin=secondary, stdout=secondary,
                           stderr=secondary)
    os.close(secondary)
    seen = bytearray()
    try:
        while True:
            try:
                chunk = os.read(primary, 65536)
            except OSError:  # the run closed the terminal
                break
            if not chunk:
                break
            seen += chunk
    finally:
        run.wait(60)
        os.close(primary)
    text = seen.decode(errors="replace")
    assert run.returncode == 0, text
    assert "episode 1 of 2: " in text and "episode 2 of 2: " in text  # the episode lines, printed above
    flat = re.sub(r"\s+", " ", re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", text))  # the status line wraps at 80 columns
    assert "LEARNING | episode " in flat and "| depth " in flat and " V | rtt " in flat  # the live status line
    # the recording's path comes on a line of its own once the status line has ended, not glued to its last line
    lines = [re.sub(r"\x1b\[[0-9;?]*[A-Za-z]", "", line).strip() for line in re.split(r"[\r\n]+", text)]
    recorded = sorted((tmp_path / "rec").glob("*.mcap"))
    assert recorded and str(recorded[0]) in lines, lines[-8:]
