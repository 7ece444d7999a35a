"""Issue 13 item 3: stopping is always clean. SIGTERM and SIGHUP to `dive run` do what Ctrl-C does (CMD_STOP, the
footer, the path printed, the sim:// child stopped); no kill, not even kill -9, leaves a virtual agent running."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from groundstation.recording.info import summarize
from simulator.parameters import preset
from simulator.serve.loop import AgentServer, ServeConfig
from tests.reliability.recordings import DIVE_MAIN, ROOT


def children(pid: int) -> list[int]:
    found: list[int] = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        found += [int(x) for x in (task / "children").read_text().split()]
    return found


def alive(pid: int) -> bool:
    try:
        state = next(line for line in Path(f"/proc/{pid}/status").read_text().splitlines()
                     if line.startswith("State:"))
    except (OSError, StopIteration):
        return False
    return " Z " not in state and "zombie" not in state


def gone_within(pid: int, seconds: float) -> bool:
    deadline = time.monotonic() + seconds
    while alive(pid):
        if time.monotonic() > deadline:
            return False
        time.sleep(0.1)
    return True


def start_run(out: Path) -> tuple[subprocess.Popen[str], int]:
    """`dive run sim://` recording into `out`; returns it and its virtual agent's pid once learning is recorded."""
    proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "run", "sim://?speed=5&seed=3", "--out", str(out)],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    deadline = time.monotonic() + 120  # the first start of the simulator compiles its kernels
    while not any(p.stat().st_size > 0 for p in out.glob("*.mcap")) or not children(proc.pid):
        assert proc.poll() is None and time.monotonic() < deadline, proc.stderr.read() if proc.stderr else ""
        time.sleep(0.2)
    time.sleep(2.0)  # CMD_START sent, samples flowing
    (child,) = children(proc.pid)
    return proc, child


@pytest.mark.slow
@pytest.mark.parametrize("signum", [signal.SIGTERM, signal.SIGHUP])
def test_sigterm_and_sighup_stop_dive_run_as_ctrl_c_does(signum: int, tmp_path: Path) -> None:
    proc, child = start_run(tmp_path)
    proc.send_signal(signum)
    out, err = proc.communicate(timeout=90)
    assert proc.returncode == 130, err  # stopped as by Ctrl-C: the one exit-code convention (README, issue 14)
    (path,) = tmp_path.glob("*.mcap")
    assert str(path) in out.splitlines()  # the path printed
    assert f"stopped by {signal.Signals(signum).name}" in err
    summary = summarize(path)
    assert summary.complete and summary.samples > 0  # the footer written
    assert summary.topics.get("/ground/CMD_STOP", 0) >= 1  # the agent told to stop, not left learning
    assert gone_within(child, 10), "the sim:// child stopped"


@pytest.mark.slow
def test_kill_9_of_dive_run_or_dive_sim_leaves_no_agent_running(tmp_path: Path) -> None:
    proc, child = start_run(tmp_path)
    proc.kill()
    proc.wait(10)
    assert gone_within(child, 10), "the sim:// child of a killed dive run"
    sim = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "sim", "--tcp", "127.0.0.1:0"],
                           stdout=subprocess.PIPE, text=True, cwd=ROOT)
    assert sim.stdout is not None and sim.stdout.readline().startswith("tcp://")
    (agent,) = children(sim.pid)
    os.kill(sim.pid, signal.SIGKILL)
    sim.wait(10)
    assert gone_within(agent, 10), "the agent of a killed dive sim"


def test_a_stop_before_the_agent_loop_starts_is_kept() -> None:
    """The race behind a killed `dive sim` leaving its agent running (seen once in the suite): the parent died just
    after the agent printed its address, its SIGTERM handler called stop() before serve_forever() began, and the
    loop's start used to forget it. A real server on a real port, stopped first: serve_forever() returns at once."""
    server = AgentServer(ServeConfig(plant=preset("paper"), port=0, seed=1))
    server.stop()
    started = time.monotonic()
    server.serve_forever()
    assert time.monotonic() - started < 1.0
