"""How far the live view lags behind the agent, at --speed 1, 100 and max, as a viewer receives it.

Run: `.venv/bin/python benchmarks/viewer_lag_bench.py [--seconds 10]`. Not a test: it prints figures.

What `dive run --viewer web` does is set up here: the virtual agent learning, the session recording to MCAP, the
live view (RerunView) serving its stream from a Rerun gRPC server, as a browser's viewer reads it. The viewer is
Rerun's own client, `rerun rerun+http://.../proxy --save FILE`: it takes the stream from that server exactly as
the viewer does and appends it to FILE. Every `--every` seconds the file is copied; afterwards each copy is read
back with Rerun (rerun.chunk.RrdReader) for the newest agent time it holds. The lag at the copy's wall time T:
- ground → viewer [s]: T minus when the session received the SAMPLE of that newest agent time;
- agent seconds behind: the newest agent time the session had received by T minus the viewer's;
- the link's own delay (agent → ground) is under the PARAM_GET round trip, sampled in the same run.
What this cannot see: the viewer's rendering. A browser drawing on a software rasteriser (a VM without a GPU)
can fall far behind its own data; that is the browser's frame rate, not the stream.
The anchor is the same set-up at --speed 1 (10 SAMPLEs a second), measured in the same run; goal (issue 14):
the viewer within 1 s of the agent at any speed.
"""

from __future__ import annotations

import argparse
import bisect
import shutil
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
import warnings
from pathlib import Path

import rerun.chunk as rrc

from groundstation.links import make_link
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import LinkEvent, Received, Sent
from groundstation.view.options import Viewer
from groundstation.view.rerun_sink import RerunView, ViewConfig
from protocol import messages as m

SPEEDS = ("1", "100", "max")  # the first is the anchor
DEPTH_ENTITY = "/depth/z_up_m"


class SampleTimes:
    """The session's side: when (wall ns) each SAMPLE's agent time reached the ground, in arrival order."""

    def __init__(self) -> None:
        self.arrived_ns: list[int] = []
        self.agent_us: list[int] = []
        self.by_agent_us: dict[int, int] = {}

    def on_received(self, received: Received) -> None:
        message = received.frame.message
        if isinstance(message, m.Sample) and not received.backfilled:
            self.arrived_ns.append(received.host_time_ns)
            self.agent_us.append(message.t_us)
            self.by_agent_us.setdefault(message.t_us, received.host_time_ns)

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        pass

    def newest_by(self, wall_ns: int) -> int | None:
        """Agent time of the newest SAMPLE received by wall_ns (arrival order is wall order)."""
        i = bisect.bisect_right(self.arrived_ns, wall_ns)
        return max(self.agent_us[:i]) if i else None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def rerun_executable() -> str:
    return shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))


def newest_agent_us(snapshot: Path) -> int | None:
    """The newest agent time of the depth plot in a copy of the viewer's stream, read back with Rerun."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # a stream cut mid-way has no footer: Rerun warns and scans it whole
        store = rrc.RrdReader(snapshot).stream().collect()
    newest: int | None = None
    for chunk in store.stream():
        if chunk.entity_path != DEPTH_ENTITY or chunk.is_static:
            continue
        column = chunk.to_record_batch().column("agent_time").cast("int64").to_pylist()  # duration[ns]
        if column:  # seconds as f64 became whole ns: round back to the agent's whole microseconds
            newest = max(newest or 0, (max(column) + 500) // 1000)
    return newest


def _copy_every(source: Path, folder: Path, every_s: float, stop: threading.Event,
                copies: list[tuple[int, Path]]) -> None:
    while not stop.wait(every_s):
        if source.exists():
            target = folder / f"copy{len(copies):04d}.rrd"
            shutil.copyfile(source, target)
            copies.append((time.time_ns(), target))


def _round_trips(session: Session, stop: threading.Event, rtts: list[float]) -> None:
    while not stop.wait(0.5):
        began = time.perf_counter()
        session.command(m.ParamGet(index=0, name=""), timeout_s=60.0)
        rtts.append(time.perf_counter() - began)


def measure(speed: str, seconds: float, every_s: float, folder: Path) -> dict[str, list[float]]:
    """One run at `speed`: lags per copy of the viewer's stream, and PARAM_GET round trips, in seconds."""
    work = folder / speed
    work.mkdir()
    grpc_port, web_port = free_port(), free_port()
    recorder = Recorder(RecorderConfig(directory=work), {"url": f"sim://?speed={speed}"})
    times = SampleTimes()
    view = RerunView.open(ViewConfig(viewer=Viewer.WEB, grpc_port=grpc_port, web_port=web_port), f"lag-{speed}")
    saved = work / "viewer.rrd"
    # --port: the client also hosts a gRPC server of its own, on 9876 unless told otherwise.
    viewer = subprocess.Popen([rerun_executable(), f"rerun+http://127.0.0.1:{grpc_port}/proxy", "--save",
                               str(saved), "--port", str(free_port())],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    run = Session(make_link(f"sim://?speed={speed}&seed=1"), SessionConfig(), [recorder, times, view])
    copies: list[tuple[int, Path]] = []
    rtts: list[float] = []
    stop = threading.Event()
    workers = [threading.Thread(target=_copy_every, args=(saved, work, every_s, stop, copies)),
               threading.Thread(target=_round_trips, args=(run, stop, rtts))]
    try:
        run.connect()
        run.command(m.StartLearning(max_episodes=0))
        for worker in workers:
            worker.start()
        time.sleep(seconds)
    finally:
        stop.set()
        for worker in workers:
            worker.join()
        run.close()
        view.close()
        recorder.close()
        viewer.terminate()
        viewer.wait(10)
    behind_s: list[float] = []
    behind_agent_s: list[float] = []
    for copied_ns, copy in copies[2:]:  # the first second: the viewer client is still connecting
        shown_us = newest_agent_us(copy)
        received_us = times.newest_by(copied_ns)
        if shown_us is None or received_us is None or shown_us not in times.by_agent_us:
            continue
        behind_s.append((copied_ns - times.by_agent_us[shown_us]) / 1e9)
        behind_agent_s.append((received_us - shown_us) / 1e6)
    return {"wall": behind_s, "agent": behind_agent_s, "rtt": rtts, "samples": [float(len(times.agent_us))]}


def _p95(values: list[float]) -> float:
    return statistics.quantiles(values, n=20)[-1] if len(values) >= 20 else max(values)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=10.0, help="measuring time per speed")
    parser.add_argument("--every", type=float, default=0.25, help="seconds between copies of the viewer's stream")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        results = {speed: measure(speed, args.seconds, args.every, Path(tmp)) for speed in SPEEDS}
    anchor = statistics.median(results[SPEEDS[0]]["wall"])
    print(f"{'speed':<6} {'ground->viewer [s]: p50':>24} {'p95':>6} {'max':>6} {'ratio to speed 1':>17} "
          f"{'agent s behind p50':>19} {'max':>7} {'RTT p50 [ms]':>13} {'SAMPLEs':>8}  goal < 1 s")
    for speed, r in results.items():
        wall, agent = r["wall"], r["agent"]
        if not wall:
            print(f"{speed:<6} no copy of the viewer's stream held a SAMPLE")
            continue
        worst = max(wall) + statistics.median(r["rtt"])  # plus the link's own delay, bounded by a round trip
        print(f"{speed:<6} {statistics.median(wall):24.3f} {_p95(wall):6.3f} {max(wall):6.3f} "
              f"{statistics.median(wall) / anchor:16.2f}x {statistics.median(agent):19.1f} {max(agent):7.1f} "
              f"{statistics.median(r['rtt']) * 1e3:13.1f} {int(r['samples'][0]):8d}  "
              f"{'ok' if worst < 1.0 else 'over 1 s'} (worst + RTT {worst:.3f} s)")


if __name__ == "__main__":
    main()
