"""A second recorder through the hub (issue 14 item 1): `dive record` beside a `dive run` records the same telemetry
without taking the agent's one link. Real processes and real TCP, as in test_hub.py."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from groundstation.mcap_io import iter_messages
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import DIVE, dive_env, running


def _samples(folder: Path) -> dict[int, bytes]:
    """Sample index -> the SAMPLE's JSON without its frame envelope (seq and flags differ per link)."""
    found: dict[int, bytes] = {}
    for path in sorted(folder.glob("*.mcap")):
        for msg in iter_messages(path, {"/agent/SAMPLE"}):
            body = json.loads(msg.data)
            for key in ("_seq", "_flags", "_backfilled"):
                body.pop(key)
            found[body["sample"]] = json.dumps(body, sort_keys=True).encode()
    return found


@pytest.mark.slow
def test_a_second_recorder_through_the_hub_records_the_same_samples(tmp_path: Path) -> None:
    agent = FakeAgent()
    runtime = tmp_path / "runtime"
    try:
        with running(runtime, agent.url, tmp_path / "run") as run:
            second = subprocess.Popen([*DIVE, "record", "--out", str(tmp_path / "second"), "--split-mb", "0.05"],
                                      env=dive_env(runtime), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            deadline = time.monotonic() + 60
            # The agent learns on and both recorders take its frames, until the second has begun its second part.
            while time.monotonic() < deadline and len(list((tmp_path / "second").glob("*.mcap"))) < 2:
                time.sleep(0.05)
            time.sleep(0.5)
            run.send_signal(signal.SIGINT)  # the run ends first: the second recorder ends with it
            out, err = second.communicate(timeout=30)
        run.communicate()
    finally:
        agent.close()
    assert second.returncode == 0 and "the run ended; the recording is complete" in err, err
    assert "Traceback" not in err
    parts = [Path(line) for line in out.splitlines()]
    assert len(parts) >= 2 and all(p.name.endswith(f"-part{i:03d}.mcap") for i, p in enumerate(parts, 1))
    assert agent.connections == 1  # the second recorder took nothing from the agent's one link
    of_run, of_second = _samples(tmp_path / "run"), _samples(tmp_path / "second")
    assert len(of_second) > 100, len(of_second)
    first, last = min(of_second), max(of_second)
    # Every SAMPLE the run recorded while the second recorder was attached, in both, the same values.
    assert {i: of_run[i] for i in of_run if first <= i <= last} == of_second
