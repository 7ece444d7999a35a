"""Another local user can neither read nor command a run, keyed or not (issue 25 C1): a real second account.

Needs root (to run the intruder as `nobody`); skipped with one line elsewhere.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from groundstation.mcap_io import read_recording
from protocol.signing import KEY_SIZE
from tests.groundstation.fake_agent import FakeAgent
from tests.security.attack import RunInThread, as_another_user
from tests.waiting import wait_for

ROOT = Path(__file__).resolve().parents[2]
SYSTEM_PYTHON = shutil.which("python3", path="/usr/bin:/bin")  # the intruder's: outside root's home, stdlib only
pytestmark = [pytest.mark.skipif(os.geteuid() != 0, reason="needs root to act as another local user (nobody)"),
              pytest.mark.skipif(SYSTEM_PYTHON is None, reason="no system python3 for the other user to run")]


@pytest.mark.parametrize("key", [None, bytes(range(KEY_SIZE))], ids=["unkeyed", "keyed"])
def test_another_user_can_neither_read_nor_command_a_run(tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
                                                         key: bytes | None) -> None:
    # A runtime folder others can reach (as ~/.cache is on many systems): only the run's own modes keep them out.
    shared = Path(tempfile.mkdtemp(prefix="dive-runtime-"))
    shared.chmod(0o755)
    monkeypatch.setenv("DIVE_RUNTIME_DIR", str(shared))
    agent = FakeAgent()
    try:
        from groundstation.session.agent_session import SessionConfig

        job = RunInThread(agent.url, tmp_path / "rec", SessionConfig(key=key, backoff_s=(0.05, 0.2)))
        assert wait_for(lambda: agent.learning and any((shared / "runs").glob("*.json")))
        [announced] = (shared / "runs").glob("*.json")
        port = json.loads(announced.read_text())["hub"].rsplit(":", 1)[1]
        before = list(agent.executed)
        intruder = [SYSTEM_PYTHON or sys.executable, str(Path(__file__).with_name("intruder.py"))]
        done = subprocess.run([*intruder, str(shared / "runs"), port], cwd=ROOT,
                              env={"PYTHONPATH": str(ROOT), "PATH": os.environ["PATH"]}, capture_output=True,
                              text=True, timeout=30, **as_another_user())
        assert done.returncode == 0, done.stderr
        report = json.loads(done.stdout)
        job.stop()
    finally:
        agent.close()
        shutil.rmtree(shared, ignore_errors=True)
    assert job.error is None, job.error
    assert report["read"] == [] and report["frames"] == 0, report  # no token, no telemetry
    assert agent.executed[len(before):].count("PARAM_SET") == 0 and "CMD_SURFACE" not in agent.executed
    [recording] = (tmp_path / "rec").glob("*.mcap")
    assert read_recording(recording, {"/marker"}).messages == []  # nothing written into the owner's recording
