"""The run's markers and alarms reach its attached tools (issue 28: `dive mark` into a `dive record`; issue 27: alarms
in a `dive view` on the hub). Real processes: a `dive run` on the virtual agent, a `dive record` and a `dive view`
attached to its hub, `dive mark` and `dive params set`; both MCAP files read back with mcap, the view's .rrd with
Rerun's own reader."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest
from mcap.reader import make_reader

from groundstation.links.hub_events import TEXT_BYTES, ground_text, parse_ground_text
from tests.groundstation.hub_helpers import DIVE, SIM, dive, dive_env, running
from tests.groundstation.rrd_readback import component_rows


def _events(folder: Path) -> tuple[list[str], list[dict[str, object]]]:
    """The /marker texts and /event records of every MCAP file in `folder`."""
    markers: list[str] = []
    events: list[dict[str, object]] = []
    for path in sorted(folder.glob("*.mcap")):
        with path.open("rb") as f:
            for _, channel, message in make_reader(f).iter_messages(topics=["/marker", "/event"]):
                body = json.loads(message.data)
                if channel.topic == "/marker":
                    markers.append(body["text"])
                else:
                    events.append(body)
    return markers, events


@pytest.mark.slow
def test_a_marker_and_an_alarm_reach_a_second_recorder_and_an_attached_view(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    tools: list[subprocess.Popen[str]] = []
    env = {**dive_env(runtime), "PYTHONUNBUFFERED": "1"}
    with running(runtime, SIM, tmp_path / "run") as run:
        try:
            for args in (["record", "--out", str(tmp_path / "second")],
                         ["view", "--viewer", "none", "--rrd", str(tmp_path / "view.rrd")]):
                tools.append(subprocess.Popen([*DIVE, *args], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                              text=True))
            record, view = tools
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline and not list((tmp_path / "second").glob("*.mcap")):
                time.sleep(0.1)
            assert view.stdout is not None
            line = view.stdout.readline()  # unbuffered (dive_env): the line comes once the view's session is up
            assert line.startswith("watching"), (line, view.communicate())
            marked = dive(runtime, "mark", "ballast checked")
            assert marked.returncode == 0, marked.stderr
            # low_batt_v 4.1: the battery (4.2 V full) is within the alarm's 0.1 V margin at the next HEARTBEAT, after
            # both tools attached (an alarm is said once, when its condition starts)
            changed = dive(runtime, "params", "set", "low_batt_v", "4.1")
            assert changed.returncode == 0, changed.stderr
            time.sleep(2.5)
            for tool in tools:
                tool.send_signal(signal.SIGINT)
            for tool in tools:
                tool.communicate(timeout=30)
        finally:
            for tool in tools:
                if tool.poll() is None:
                    tool.kill()
                    tool.wait()
    _, run_err = run.communicate()
    assert record.returncode in (0, 130) and view.returncode == 130, (record.returncode, view.returncode)
    assert "ALARM: battery low" in run_err, run_err
    for folder in (tmp_path / "run", tmp_path / "second"):  # the run's recording and the second one alike
        markers, events = _events(folder)
        assert markers == ["ballast checked"], (folder, markers)
        alarms = [e for e in events if e["kind"] == "alarm"]
        assert [e["data"] for e in alarms] == [{"alarm": "battery"}], (folder, events)
        assert str(alarms[0]["detail"]).startswith("battery low: 4."), alarms
    logged = [row["TextLog:text"] for row in component_rows(tmp_path / "view.rrd", "/log/events")]
    texts = [text for row in logged for text in (row if isinstance(row, list) else [row])]
    assert any(t.startswith("alarm: battery low") for t in texts), texts
    assert "marker: ballast checked" in texts, texts


def test_a_ground_text_round_trips_and_is_cut_to_fit_a_text_frame() -> None:
    alarm = ground_text("alarm", "battery low: 3.61 V", {"alarm": "battery"})
    assert alarm.severity == 3 and parse_ground_text(alarm.text) == ("alarm", "battery low: 3.61 V",
                                                                      {"alarm": "battery"})
    long = "é" * 200  # 400 bytes: cut on a character to fit the frame, the marker's text its detail
    marker = ground_text("marker", long, {"text": long})
    assert len(marker.text.encode()) <= TEXT_BYTES
    kind, detail, data = parse_ground_text(marker.text) or ("", "", {})
    assert kind == "marker" and long.startswith(detail) and len(detail) > 100 and data == {"text": detail}
    assert parse_ground_text("an agent's line") is None and parse_ground_text("alarm\x1fnot json\x1fx") is None
