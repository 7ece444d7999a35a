"""A second recorder through the hub (issue 14 item 1): `dive record` beside a `dive run` records the same telemetry
without taking the agent's one link; and the run's markers and alarms, which happen on the ground, reach it and a
`dive view` attached beside it (issue 28: `dive mark` into a second recording; issue 27: alarms in an attached view).
Real processes and real TCP, as in test_hub.py; both MCAP files read back with mcap, the view's .rrd with Rerun."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from groundstation.links.hub_events import TEXT_BYTES, ground_text, parse_ground_text
from groundstation.mcap_io import iter_messages
from tests.groundstation.fake_agent import FakeAgent
from tests.groundstation.hub_helpers import DIVE, dive, dive_env, running
from tests.groundstation.rrd_readback import component_rows


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


def _ground_events(folder: Path) -> tuple[list[str], list[str]]:
    """The /marker texts and the alarms' details on /event of every MCAP file in `folder`."""
    markers: list[str] = []
    alarms: list[str] = []
    for path in sorted(folder.glob("*.mcap")):
        for msg in iter_messages(path, {"/marker", "/event"}):
            body = json.loads(msg.data)
            if "text" in body:
                markers.append(body["text"])
            elif body["kind"] == "alarm":
                alarms.append(body["detail"])
    return markers, alarms


@pytest.mark.slow
def test_a_second_recorder_through_the_hub_records_the_same_samples_markers_and_alarms(tmp_path: Path) -> None:
    agent = FakeAgent(depth_step_m=0.01)
    runtime = tmp_path / "runtime"
    env = {**dive_env(runtime), "PYTHONUNBUFFERED": "1"}  # the view's "watching" line as soon as it is said
    try:
        # the fake agent's depth climbs 0.50 -> 0.69 m in every episode: a depth alarm past 0.6 m, cleared below
        # 0.55 m (its hysteresis) at the next episode's start, ten a second
        with running(runtime, agent.url, tmp_path / "run", "--alarm-depth", "0.6") as run:
            second = subprocess.Popen([*DIVE, "record", "--out", str(tmp_path / "second"), "--split-mb", "0.05"],
                                      env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            view = subprocess.Popen([*DIVE, "view", "--viewer", "none", "--rrd", str(tmp_path / "view.rrd")],
                                    env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            try:
                assert view.stdout is not None and view.stdout.readline().startswith("watching"), view.stderr
                marked = dive(runtime, "mark", "ballast checked")
                assert marked.returncode == 0, marked.stderr
                deadline = time.monotonic() + 60
                # The agent learns on and both recorders take its frames, until the second has begun its second part.
                while time.monotonic() < deadline and len(list((tmp_path / "second").glob("*.mcap"))) < 2:
                    time.sleep(0.05)
                time.sleep(0.5)
                view.send_signal(signal.SIGINT)
                view.communicate(timeout=30)
            finally:
                if view.poll() is None:
                    view.kill()
            run.send_signal(signal.SIGINT)  # the run ends first: the second recorder ends with it
            out, err = second.communicate(timeout=30)
        run.communicate()
    finally:
        agent.close()
    assert second.returncode == 0 and "the run ended; the recording is complete" in err, err
    assert view.returncode == 130
    assert "Traceback" not in err
    parts = [Path(line) for line in out.splitlines()]
    assert len(parts) >= 2 and all(p.name.endswith(f"-part{i:03d}.mcap") for i, p in enumerate(parts, 1))
    assert agent.connections == 1  # the second recorder took nothing from the agent's one link
    of_run, of_second = _samples(tmp_path / "run"), _samples(tmp_path / "second")
    assert len(of_second) > 100, len(of_second)
    first, last = min(of_second), max(of_second)
    # Every SAMPLE the run recorded while the second recorder was attached, in both, the same values.
    assert {i: of_run[i] for i in of_run if first <= i <= last} == of_second
    # The run's marker and alarms, which no agent frame carries, in the second recording too: each alarm it holds is
    # one the run said (and recorded), the marker once.
    (run_markers, run_alarms), (markers, alarms) = _ground_events(tmp_path / "run"), _ground_events(tmp_path / "second")
    assert run_markers == markers == ["ballast checked"], (run_markers, markers)
    assert alarms and set(alarms) <= set(run_alarms) and all("past the 0.6 m limit" in a for a in alarms), alarms
    # and in the view attached beside it, in its event log as the run's own view shows them
    texts = [text for row in component_rows(tmp_path / "view.rrd", "/log/events") for text in row["TextLog:text"]]
    assert "marker: ballast checked" in texts and any(t.startswith("alarm: depth") for t in texts), texts


def test_a_ground_text_round_trips_and_is_cut_to_fit_a_text_frame() -> None:
    alarm = ground_text("alarm", "battery low: 3.61 V", {"alarm": "battery"})
    assert alarm.severity == 3
    assert parse_ground_text(alarm.text) == ("alarm", "battery low: 3.61 V", {"alarm": "battery"})
    long = "é" * 200  # 400 bytes: cut on a character to fit the frame, the marker's text its detail
    marker = ground_text("marker", long, {"text": long})
    assert len(marker.text.encode()) <= TEXT_BYTES
    kind, detail, data = parse_ground_text(marker.text) or ("", "", {})
    assert kind == "marker" and long.startswith(detail) and len(detail) > 100 and data == {"text": detail}
    assert parse_ground_text("an agent's line") is None and parse_ground_text("alarm\x1fnot json\x1fx") is None
