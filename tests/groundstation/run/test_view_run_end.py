"""`dive view` attached to a run ends with the run: one line, exit 0, its .rrd whole; before, it went on
"watching" a hub that was gone, for ever, with nothing said. A real run process, its hub, a FakeAgent over TCP, the
recording read back by Rerun."""

from __future__ import annotations

import subprocess
import time
from pathlib import Path

import pytest
import rerun.chunk as rrc

from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import DIVE, dive_env, interrupt, running


@pytest.mark.slow
def test_a_view_of_a_run_ends_when_the_run_ends(tmp_path: Path) -> None:
    agent = FakeAgent()
    runtime, rrd = tmp_path / "runtime", tmp_path / "live.rrd"
    viewer = None
    try:
        with running(runtime, agent.url, tmp_path / "rec") as run:
            viewer = subprocess.Popen([*DIVE, "view", "--viewer", "none", "--rrd", str(rrd)], env=dive_env(runtime),
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            assert viewer.stdout is not None
            watching = viewer.stdout.readline()
            assert watching.startswith("watching "), watching + viewer.communicate(timeout=30)[1]
            time.sleep(1.0)
        assert run.returncode == 130  # the run was stopped (Ctrl-C); the view was not
        out, err = viewer.communicate(timeout=30)
        assert viewer.returncode == 0, (out, err)
        assert f"dive run {run.pid} ended and closed its hub" in out and "Traceback" not in err, (out, err)
        logged = {chunk.entity_path for chunk in rrc.RrdReader(rrd).stream().collect().stream()}
        assert any("depth" in path for path in logged), sorted(logged)
    finally:
        if viewer is not None:
            interrupt(viewer)
        agent.close()
