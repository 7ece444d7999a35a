"""The fault matrix at speed (issue 13 item 9): `dive run` against the virtual agent with every fault on at once.

    PYTHONPATH=. .venv/bin/python benchmarks/fault_matrix_bench.py [--speeds 1,10,20,50,100] [--episodes 3]
        [--foxglove]

Faults: drop 5 %, corrupt 1 %, delay 200 ms each way, disconnect every 20 s of agent time, radio blackout below
0.2 m; the hardware preset. For each speed it prints the samples the agent produced, those missing from the
recording after backfill, those recorded twice, whether the live ones are in order, and the wall time of the run.
With --foxglove the run serves Foxglove too (`--foxglove 0`) and a client is subscribed to /agent/SAMPLE all along
(issue 38: the recording must not lose a sample to a viewer); its SAMPLEs received are printed too.
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from websockets.exceptions import WebSocketException

from groundstation.recording.info import summarize
from tests.groundstation.foxglove_client import FoxgloveClient
from tests.reliability.recordings import DIVE_MAIN, dive, read
from tests.simulator.agent_client import ROOT, running

ALL_FAULTS = ["--drop", "0.05", "--corrupt", "0.01", "--delay", "200", "--disconnect-every", "20",
              "--blackout-below", "0.2"]


def _ranges(indices: list[int]) -> list[tuple[int, int]]:
    out: list[tuple[int, int]] = []
    for i in indices:
        if out and out[-1][1] == i:
            out[-1] = (out[-1][0], i + 1)
        else:
            out.append((i, i + 1))
    return out


def _watched_run(*args: str, received: list[int]) -> subprocess.CompletedProcess[str]:
    """`dive run ARGS --foxglove 0` with a Foxglove client subscribed to /agent/SAMPLE until the run ends."""
    proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, *args, "--foxglove", "0"], cwd=ROOT,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stderr is not None
    first = proc.stderr.readline()
    port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", first).group(1))  # type: ignore[union-attr]

    def watch_once() -> None:
        with FoxgloveClient.connected(port) as fox:
            subscribed: list[int] = []

            def until() -> bool:
                if not subscribed and "/agent/SAMPLE" in fox.channels:
                    subscribed.append(fox.subscribe("/agent/SAMPLE"))
                return proc.poll() is not None

            fox.pump(until, 1800)
            received.append(len(fox.messages.get(subscribed[0], [])) if subscribed else 0)

    def watch() -> None:
        for _ in range(30):  # the run's start (the simulator's, a loaded machine) can outlast one connect's wait
            try:
                watch_once()
                return
            except (OSError, WebSocketException) as e:
                print(f"  the Foxglove client: {type(e).__name__}: {e}; connecting again", file=sys.stderr)
                time.sleep(1.0)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    stdout, stderr = proc.communicate(timeout=1800)
    watcher.join(10)
    return subprocess.CompletedProcess(proc.args, proc.returncode, stdout, first + stderr)


def one_run(speed: str, episodes: int, seed: int, folder: Path, foxglove: bool = False) -> dict[str, object]:
    report = folder / "agent-report.json"
    out = folder / "rec"
    began = time.perf_counter()
    received: list[int] = []
    with running("--tcp", "127.0.0.1:0", "--preset", "hardware", "--speed", speed, "--seed", str(seed),
                 "--report", str(report), *ALL_FAULTS) as agent:
        args = ("run", agent.address, "--episodes", str(episodes), "--out", str(out))
        done = _watched_run(*args, received=received) if foxglove else dive(*args, timeout_s=1800)
    wall_s = time.perf_counter() - began
    files = sorted(out.glob("*.mcap"))
    row: dict[str, object] = {"speed": speed, "exit": done.returncode, "wall_s": round(wall_s, 1)}
    if done.returncode != 0 or len(files) != 1:
        row["error"] = (done.stderr.strip().splitlines() or ["?"])[-1]
        return row
    rec = read(files[0])
    missing, duplicated = rec.missing_and_duplicated()
    row["dive_says"] = [line for line in done.stderr.splitlines() if "samples" in line]
    row["missing_ranges"] = _ranges(missing)[:8]
    agent_report = json.loads(report.read_text())
    summary = summarize(files[0])
    row.update(samples=len(set(rec.indices)), missing=len(missing), duplicated=len(duplicated),
               in_order=rec.live_in_order(), episodes=len(set(rec.episode_ends)),
               backfilled=summary.samples_backfilled, reconnects=rec.link[-1]["link"]["reconnects"],
               frames_dropped_by_agent=agent_report["out"].get("dropped"))
    if foxglove:
        row["foxglove_samples_received"] = received[0] if received else 0
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--speeds", default="1,10,20,50,100")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument("--foxglove", action="store_true", help="serve Foxglove, a client subscribed to SAMPLEs")
    args = parser.parse_args()
    rows = []
    for speed in args.speeds.split(","):
        with tempfile.TemporaryDirectory() as folder:
            row = one_run(speed, args.episodes, args.seed, Path(folder), args.foxglove)
        rows.append(row)
        print(json.dumps(row), flush=True)
    print(f"\n{'speed':>6} {'episodes':>8} {'samples':>8} {'missing':>8} {'duplicated':>10} {'ordered':>8} "
          f"{'backfilled':>10} {'reconnects':>10} {'wall s':>7}")
    for r in rows:
        if "error" in r:
            print(f"{r['speed']:>6} error: {r['error']}")
            continue
        print(f"{r['speed']:>6} {r['episodes']:>8} {r['samples']:>8} {r['missing']:>8} {r['duplicated']:>10} "
              f"{r['in_order']!s:>8} {r['backfilled']:>10} {r['reconnects']:>10} {r['wall_s']:>7}")
    print(f"load: {subprocess.run(['uptime'], capture_output=True, text=True).stdout.strip()}", file=sys.stderr)


if __name__ == "__main__":
    main()
