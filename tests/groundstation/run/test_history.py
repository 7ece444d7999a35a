"""History on attach (issue 27 item 4): a tool attaching to a running `dive run` late gets the run's episode table,
its last dumps and its recent telemetry (bounded) before the live stream. A real run on the virtual agent, its hub,
a real session attached over TCP, and `dive view` as a process."""

from __future__ import annotations

import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest

from groundstation.links import make_link
from groundstation.links.runs import attach_url
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import DumpKind
from protocol import messages as m
from tests.groundstation.hub_helpers import DIVE, SIM, dive_env, running

pytestmark = pytest.mark.slow


class _Frames:
    def __init__(self) -> None:
        self.received: list[Received] = []

    def on_received(self, received: Received) -> None:
        self.received.append(received)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass


def _episodes(frames: _Frames, replayed: bool) -> list[int]:
    return [r.message.episode for r in frames.received
            if isinstance(r.message, m.EpisodeEnd) and r.backfilled == replayed]


def test_a_late_tool_gets_the_episode_table_the_last_dumps_and_bounded_telemetry(tmp_path: Path,
                                                                                  monkeypatch: pytest.MonkeyPatch,
                                                                                  ) -> None:
    runtime = tmp_path / "runtime"
    monkeypatch.setenv("DIVE_RUNTIME_DIR", str(runtime))
    # 6 s of telemetry at most: at 20x real time, 120 s of agent time
    with running(runtime, SIM, tmp_path / "rec", "--success-time", "5", "--history-minutes", "0.1",
                 start_timeout_s=120):
        deadline = time.monotonic() + 90
        while time.monotonic() < deadline:  # until the agent has done 4 episodes
            with Session(make_link(attach_url(None)), SessionConfig(reconnect=False, backfill=False)) as probe:
                beat_deadline = time.monotonic() + 2.0
                while probe.last_heartbeat is None and time.monotonic() < beat_deadline:
                    time.sleep(0.05)
                if probe.last_heartbeat is not None and probe.last_heartbeat.episode > 4:
                    break
            time.sleep(1.0)
        time.sleep(8.0)  # the first episodes leave the telemetry window
        late = _Frames()
        with Session(make_link(attach_url(None)), SessionConfig(reconnect=False, backfill=False), [late]) as tool:
            tool.command(m.LogRequest(first_sample=0, end_sample=0xFFFFFFFF))
            ends = time.monotonic() + 15
            while not any(isinstance(r.message, m.LogRange) for r in late.received) and time.monotonic() < ends:
                time.sleep(0.05)  # the LOG_RANGE ends the replay
            dumps = {kind: tool.dumps.newest_since(kind, 0.0) for kind in (DumpKind.VALUES, DumpKind.POLICY)}
        viewer = subprocess.Popen([*DIVE, "view", "--viewer", "none", "--rrd", str(tmp_path / "live.rrd")],
                                  env=dive_env(runtime), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        guard = threading.Timer(90.0, viewer.kill)  # a viewer that never says it watches fails, not hangs
        guard.start()
        assert viewer.stdout is not None
        said = [viewer.stdout.readline() for _ in range(1)]
        while said[-1] and "watching" not in said[-1]:
            said.append(viewer.stdout.readline())
        guard.cancel()
        time.sleep(2.0)
        viewer.send_signal(signal.SIGINT)
        view_out, view_err = viewer.communicate(timeout=30)
        view_out = "".join(said) + view_out
    replayed = _episodes(late, replayed=True)
    live = _episodes(late, replayed=False)
    assert replayed[:4] == [1, 2, 3, 4], replayed  # the whole episode table, from the first, in order
    assert replayed == sorted(set(replayed))
    assert sorted(set(replayed) | set(live)) == list(range(1, max(replayed + live) + 1))  # no episode missing
    samples = [r.message for r in late.received if isinstance(r.message, m.Sample) and r.backfilled]
    assert samples, "no telemetry replayed"
    # bounded: the window is 20 s of host time at 20x, about 400 s of agent time, not the whole run's
    first_episode_end = min(r.message.t_us for r in late.received if isinstance(r.message, m.EpisodeEnd))
    assert samples[0].t_us > first_episode_end, "the telemetry window was not bounded"
    assert all(b.sample > a.sample for a, b in zip(samples, samples[1:], strict=False))
    assert dumps[DumpKind.VALUES] is not None and dumps[DumpKind.POLICY] is not None  # the last dumps, whole
    assert viewer.returncode == 130, view_err
    assert "watching" in view_out
    assert (tmp_path / "live.rrd").stat().st_size > 10_000
