"""Foxglove answers the run's owner only (issue 38 N1): another local user, at the port the run printed and at the
SDK's own port behind it, reads no channel, sets no parameter and calls no service, on a keyed run too.

Needs root (to run the intruder as `nobody`); skipped with one line elsewhere.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from groundstation.session.agent_session import SessionConfig
from groundstation.view.foxglove.live import FoxgloveLive
from protocol.signing import KEY_SIZE
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.foxglove_client import FoxgloveClient
from tests.security.attack import RunInThread, as_another_user
from tests.waiting import wait_for

ROOT = Path(__file__).resolve().parents[2]
SYSTEM_PYTHON = shutil.which("python3", path="/usr/bin:/bin")  # the intruder's: outside root's home, stdlib only
COMMANDS = ("CMD_SURFACE", "CMD_STOP", "CMD_PAUSE", "PARAM_SET")
pytestmark = [pytest.mark.skipif(os.geteuid() != 0, reason="needs root to act as another local user (nobody)"),
              pytest.mark.skipif(SYSTEM_PYTHON is None, reason="no system python3 for the other user to run")]


def intrude(port: int) -> dict[str, object]:
    done = subprocess.run([SYSTEM_PYTHON or sys.executable, str(Path(__file__).with_name("foxglove_intruder.py")),
                           str(port)], cwd="/", env={"PATH": os.environ["PATH"]}, capture_output=True, text=True,
                          timeout=30, **as_another_user())
    assert done.returncode == 0, done.stderr
    report: dict[str, object] = json.loads(done.stdout)
    return report


@pytest.mark.parametrize("key", [None, bytes(range(KEY_SIZE))], ids=["unkeyed", "keyed"])
def test_another_user_gets_nothing_from_foxglove_at_either_port(tmp_path: Path, key: bytes | None) -> None:
    agent = FakeAgent()
    fox = FoxgloveLive(0, "test")
    try:
        job = RunInThread(agent.url, tmp_path / "rec", SessionConfig(key=key, backoff_s=(0.05, 0.2)),
                          listeners=[fox.listener])
        runs = Path(os.environ["DIVE_RUNTIME_DIR"]) / "runs"
        assert wait_for(lambda: agent.learning and any(runs.glob("*.json")))
        fox.attach_in_background("hub://", key, lambda line: None).join(10)
        assert fox.session is not None
        with FoxgloveClient.connected(fox.port) as owner:  # the owner's app: let through, sent the samples
            assert owner.pump(lambda: "/agent/SAMPLE" in owner.channels and "surface" in owner.services, 10)
            samples = owner.subscribe("/agent/SAMPLE")
            assert owner.pump(lambda: len(owner.messages.get(samples, [])) >= 5, 10)
            before = list(agent.executed)
            at_door, behind = intrude(fox.port), intrude(fox.server.port)
            assert owner.get_parameters(["target_depth_m"], 10)  # the owner's panel still answered
            executed = agent.executed[len(before):]  # (the run's own CMD_STOP at its end comes after)
        job.stop()
    finally:
        fox.close()
        agent.close()
    assert job.error is None, job.error
    assert "403" in str(at_door["status"]) and at_door["data"] == 0, at_door  # the door: refused before a frame
    # behind it (anyone can find the SDK's port): names only; no data, no parameter, no service answered
    assert str(behind["status"]).startswith("HTTP/1.1 101"), behind
    assert (behind["data"], behind["parameters"], behind["answers"]) == (0, 0, 0), behind
    assert behind["failures"] == 4, behind  # surface, stop, pause, mark: each a failed call
    assert not [c for c in executed if c in COMMANDS], executed
    [recording] = (tmp_path / "rec").glob("*.mcap")
    assert read_recording(recording, {"/marker"}).messages == []  # no INTRUDER marker in the owner's recording


def test_another_users_silent_connections_do_not_keep_the_owner_out() -> None:
    """The door's limits are the owner's alone: another user's 100 silent connections (each held until it is
    answered or closed) are counted apart, and the owner's app gets in at once. (A guard on the door's own limits:
    the SDK's server before it had none to take.)"""
    fox = FoxgloveLive(0, "test")
    hold = ("import socket, time\nheld = []\nfor _ in range(100):\n"
            f"    try: held.append(socket.create_connection(('127.0.0.1', {fox.port}), timeout=1))\n"
            "    except OSError: pass\nprint(len(held), flush=True)\ntime.sleep(6)\n")
    squatter = subprocess.Popen([SYSTEM_PYTHON or sys.executable, "-c", hold], cwd="/", stdout=subprocess.PIPE,
                                text=True, **as_another_user())
    try:
        assert squatter.stdout is not None
        assert int(squatter.stdout.readline()) > 0
        with FoxgloveClient.connected(fox.port) as owner:
            assert owner.pump(lambda: bool(owner.server_info), 5)
        assert fox.gate.counts.admitted == 1
    finally:
        squatter.kill()
        squatter.wait(10)
        fox.close()
