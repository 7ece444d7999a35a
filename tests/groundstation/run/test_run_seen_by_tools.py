"""A run as the machine's other tools see it from start to end (issue 40): while it connects, `dive record` and
`dive view` wait for it (not "no `dive run` is running") and record or watch it, the view ending with the run; the
run's normal end is its end in that file, not a link loss; and a run that is over but keeps its web viewer up is one
`dive status` names, with the viewer's address.

Real processes: `dive run` on the virtual agent, `dive record`, `dive view` and `dive status` as children attached
to its hub over TCP; the second recording read back with the mcap library and `dive log info`'s reader."""

from __future__ import annotations

import json
import signal
import subprocess
import time
from pathlib import Path

import pytest

from groundstation.cli.validate import free_port
from groundstation.mcap_io import iter_messages
from groundstation.recording.info import summarize
from tests.groundstation.hub_helpers import DIVE, dive, dive_env

pytestmark = pytest.mark.slow


def _announced_state(runtime: Path) -> str:
    for path in (runtime / "runs").glob("*.json"):
        try:
            return str(json.loads(path.read_text()).get("state", ""))
        except (OSError, ValueError):
            continue  # being replaced
    return ""


def _line_with(proc: subprocess.Popen[str], text: str, timeout_s: float = 120.0) -> str:
    """The first line of the child's stderr holding `text` (read line by line, so the child never blocks)."""
    assert proc.stderr is not None
    deadline = time.monotonic() + timeout_s
    seen = []
    while time.monotonic() < deadline:
        line = proc.stderr.readline()
        if not line:
            break
        seen.append(line)
        if text in line:
            return line
    raise AssertionError(f"{text!r} not said; stderr: {''.join(seen)[-3000:]}")


def test_a_run_connecting_then_over_with_its_viewer_up_as_other_tools_see_it(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    env = {**dive_env(runtime), "PYTHONUNBUFFERED": "1"}
    # speed 5: the run's episodes last seconds, long enough for the view to open its .rrd and attach once it is up
    run = subprocess.Popen([*DIVE, "run", "sim://?speed=5&seed=4", "--episodes", "2", "--success-time", "5",
                            "--viewer", "web", "--web-port", str(free_port()), "--grpc-port", str(free_port()),
                            "--out", str(tmp_path / "run")], env=env, stdout=subprocess.PIPE,
                           stderr=subprocess.PIPE, text=True)
    record = view = None
    try:
        # Held while it connects (its virtual agent starting): a stopped process keeps the state it was in
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and _announced_state(runtime) != "connecting":
            assert run.poll() is None
            time.sleep(0.01)
        run.send_signal(signal.SIGSTOP)
        try:
            assert _announced_state(runtime) == "connecting"
            status = dive(runtime, "status")
            assert status.returncode == 0 and f"dive run {run.pid} is connecting to sim://" in status.stdout, status
            record = subprocess.Popen([*DIVE, "record", "--out", str(tmp_path / "second")], env=env,
                                      stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            waiting = _line_with(record, "waiting for it")
            assert f"dive run {run.pid} is connecting to sim://" in waiting, waiting
            view = subprocess.Popen([*DIVE, "view", "--viewer", "none", "--rrd", str(tmp_path / "view.rrd")], env=env,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            waiting = _line_with(view, "waiting for it")
            assert f"dive run {run.pid} is connecting to sim://" in waiting, waiting
        finally:
            run.send_signal(signal.SIGCONT)
        _line_with(record, "recording ")  # attached once the run's hub is up

        # The run's two episodes end it; its web viewer stays up, and dive status says where
        viewer = _line_with(run, "the run is over; the web viewer stays at ")
        address = viewer.split("stays at ", 1)[1].split(";")[0].strip()
        out, err = record.communicate(timeout=60)
        assert record.returncode == 0 and "the run ended; the recording is complete" in err, err
        assert "no `dive run`" not in err and "Traceback" not in err
        view_out, view_err = view.communicate(timeout=60)  # it watched the run, and ends with it
        assert view.returncode == 0 and f"watching sim-agent at hub://{run.pid}" in view_out, (view_out, view_err)
        assert f"dive run {run.pid} ended and closed its hub" in view_out and "Traceback" not in view_err, view_out
        status = dive(runtime, "status")
        assert status.returncode == 0, status.stderr
        assert f"dive run {run.pid} is finished (sim://" in status.stdout, status.stdout
        assert f"its web viewer is still up at {address}" in status.stdout, status.stdout
        [announced] = (runtime / "runs").glob("*.json")
        recording = json.loads(announced.read_text())["recording"]
        info = dive(runtime, "log", "info", recording)  # finished and whole: not "being recorded" any more
        assert info.returncode == 0 and "being recorded" not in info.stdout and "episodes " in info.stdout, info
        run.send_signal(signal.SIGINT)  # the viewer's Ctrl-C
        run.communicate(timeout=60)
        gone = dive(runtime, "status")
        assert gone.returncode == 1 and "no `dive run` is running" in gone.stderr, gone
    finally:
        for proc in (run, record, view):
            if proc is not None and proc.poll() is None:
                proc.send_signal(signal.SIGCONT)
                proc.kill()
                proc.wait()

    # The second recording: the run's end recorded as such, no link loss counted for it
    [second] = [Path(line) for line in out.splitlines()]
    kinds = [json.loads(msg.data)["kind"] for msg in iter_messages(second, {"/event"})]
    assert "run_ended" in kinds and "link_lost" not in kinds, kinds
    assert summarize(second).link_losses == 0
    assert any(True for _ in iter_messages(second, {"/agent/EPISODE_END"}))  # it recorded the run's episodes
