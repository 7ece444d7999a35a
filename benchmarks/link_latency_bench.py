"""Command round trip while the virtual agent learns as fast as it can, directly and through a run's hub.

Run: `.venv/bin/python benchmarks/link_latency_bench.py [--seconds 15]`. Not a test: it prints figures.

What `dive run --speed max` does is set up here: the virtual agent (sim://?speed=max) learning, the session
recording every frame to MCAP, and the hub re-serving it to a second tool (as `dive view` / `dive status`
attach). Each PARAM_GET's ACK is queued behind every frame the agent sent before it, so its round trip is
the link's queueing delay: what a viewer lags behind the agent. Goals (issue 14): RTT < 50 ms, the viewer
< 1 s behind, at any speed. The anchor, measured in the same run, is the same agent at --speed 1 (a few
frames a second: no queue), so the ratio is what the fast agent's traffic adds.
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time
from pathlib import Path

from groundstation.hub import Hub
from groundstation.links import make_link
from groundstation.links.tcp import TcpLink
from groundstation.recorder import Recorder, RecorderConfig
from groundstation.session import Session, SessionConfig
from protocol import messages as m


def _round_trips(session: Session, seconds: float) -> list[float]:
    rtts = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        began = time.perf_counter()
        session.command(m.ParamGet(index=0, name=""), timeout_s=60.0)
        rtts.append((time.perf_counter() - began) * 1000)
        time.sleep(0.1)
    return rtts


def measure(speed: str, seconds: float, folder: Path) -> dict[str, list[float] | int]:
    recorder = Recorder(RecorderConfig(directory=folder / speed), {"url": f"sim://?speed={speed}"})
    run = Session(make_link(f"sim://?speed={speed}&seed=1"), SessionConfig(), [recorder])
    run.connect()
    hub = Hub(run).start()
    run.add_listener(hub)
    tool = Session(TcpLink(hub.address), SessionConfig(reconnect=False, backfill=False))
    try:
        run.command(m.StartLearning(max_episodes=0))
        tool.connect()
        time.sleep(1.0)
        direct = _round_trips(run, seconds / 2)
        through_hub = _round_trips(tool, seconds / 2)
        frames = run.decoder.stats.frames
    finally:
        tool.close()
        hub.close()
        run.close()
        recorder.close()
    return {"direct": direct, "hub": through_hub, "frames": frames}


def _row(name: str, rtts: list[float], anchor: list[float]) -> str:
    p50, a50 = statistics.median(rtts), statistics.median(anchor)
    p95 = statistics.quantiles(rtts, n=20)[-1] if len(rtts) >= 20 else max(rtts)
    return (f"{name:<34} {p50:8.1f} {p95:8.1f} {max(rtts):8.1f} {a50:10.1f} {p50 / a50:7.1f}x  "
            f"{'ok' if p50 < 50 else 'over 50 ms'}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=15.0, help="measuring time per speed")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        anchor = measure("1", args.seconds, Path(folder))
        fast = measure("max", args.seconds, Path(folder))
    print(f"{'PARAM_GET round trip [ms]':<34} {'p50':>8} {'p95':>8} {'max':>8} {'speed 1 p50':>10} {'ratio':>8}")
    print(_row("speed max, the run's session", fast["direct"], anchor["direct"]))  # type: ignore[arg-type]
    print(_row("speed max, a tool via the hub", fast["hub"], anchor["hub"]))  # type: ignore[arg-type]
    print(f"frames the run received: {fast['frames']} at speed max, {anchor['frames']} at speed 1 "
          f"({args.seconds:g} s each)")


if __name__ == "__main__":
    main()
