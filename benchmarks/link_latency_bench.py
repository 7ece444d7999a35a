"""Command round trip while the virtual agent learns as fast as it can, directly and through a run's hub.

Run: `.venv/bin/python benchmarks/link_latency_bench.py [--seconds 15]`. Not a test: it prints figures.

What `dive run --speed max` does is set up here: the virtual agent (sim://?speed=max) learning, the session
recording every frame to MCAP, and the hub re-serving it to a second tool (as `dive view` / `dive status`
attach). Each PARAM_GET's ACK is queued behind every frame the agent sent before it, so its round trip is
the link's queueing delay: what a viewer lags behind the agent. Goals (issue 14): RTT < 50 ms, the viewer
< 1 s behind, at any speed. The anchor, measured in the same run, is the same agent at --speed 1 (a few
frames a second: no queue), so the ratio is what the fast agent's traffic adds.

The tool is a process of its own, as `dive status` or `dive view` is: in the run's process its reader would fight
the run's threads for the GIL, a cost no real tool pays (measured: 45.9 ms median that way).
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from groundstation.links import make_link
from groundstation.links.hub import HUB_RECEIVE_BUFFER_BYTES
from groundstation.links.tcp import TcpLink
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.run.hub import Hub
from groundstation.session.agent_session import Session, SessionConfig
from protocol import messages as m

ROOT = Path(__file__).resolve().parent.parent


def _round_trips(session: Session, seconds: float) -> list[float]:
    rtts = []
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        began = time.perf_counter()
        session.command(m.ParamGet(index=0, name=""), timeout_s=60.0)
        rtts.append((time.perf_counter() - began) * 1000)
        time.sleep(0.1)
    return rtts


# The tool: attaches to the hub, says it is up, measures when told to, prints its round trips as JSON.
TOOL = """
import json, sys
sys.path.insert(0, sys.argv[3])
from benchmarks.link_latency_bench import tool_round_trips
print(json.dumps(tool_round_trips(sys.argv[1], float(sys.argv[2]))), flush=True)
"""


def tool_round_trips(hub_address: str, seconds: float) -> list[float]:
    """In the tool's process: attach to the hub, say so on stdout, wait for a line on stdin, then measure."""
    link = TcpLink(hub_address, HUB_RECEIVE_BUFFER_BYTES)  # a hub:// link's (this hub is not announced by name)
    with Session(link, SessionConfig(reconnect=False, backfill=False)) as tool:
        print("attached", flush=True)
        sys.stdin.readline()
        return _round_trips(tool, seconds)


def measure(speed: str, seconds: float, folder: Path) -> dict[str, list[float] | int]:
    recorder = Recorder(RecorderConfig(directory=folder / speed), {"url": f"sim://?speed={speed}"})
    run = Session(make_link(f"sim://?speed={speed}&seed=1"), SessionConfig(), [recorder])
    run.connect()
    hub = Hub(run).start()
    run.add_listener(hub)
    tool = subprocess.Popen([sys.executable, "-c", TOOL, hub.address, str(seconds / 2), str(ROOT)],
                            stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert tool.stdin is not None and tool.stdout is not None
        run.command(m.StartLearning(max_episodes=0))
        if tool.stdout.readline().strip() != "attached":
            raise SystemExit("link_latency_bench: the tool did not attach to the hub")
        time.sleep(1.0)
        direct = _round_trips(run, seconds / 2)  # the tool attached, taking the whole stream, as in the field
        tool.stdin.write("go\n")
        tool.stdin.flush()
        figures = tool.stdout.readline()
        if not figures:
            raise SystemExit("link_latency_bench: the tool attached to the hub ended without its figures (see above)")
        through_hub = json.loads(figures)
        frames = run.decoder.stats.frames
    finally:
        tool.kill()
        tool.wait()
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
