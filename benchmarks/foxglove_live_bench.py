"""What `dive run --foxglove` costs the main job, and how much of the agent's stream a Foxglove client receives.

Run: `.venv/bin/python benchmarks/foxglove_live_bench.py [--episodes 10] [--rounds 3]`. Not a test: it prints figures.

Each round runs the same job twice, in turn: `dive run sim://?speed=max&seed=S --episodes N` alone (the anchor), and
with `--foxglove 0` and a client speaking Foxglove's protocol (tests/groundstation/foxglove_client.py) subscribed to
every /agent channel, the worst case: at --speed max the agent sends thousands of SAMPLEs a second, each published
through the run's hub, a second session and the WebSocket server. Printed per job: wall time from start to exit
(the virtual agent's start included) and the SAMPLEs recorded; the learner's episodes vary in length from run to
run even with one seed, so what is compared is SAMPLEs recorded per second from the first SAMPLE received to the
last (host times in the recording: the virtual agent's start, a few seconds, left out). For the Foxglove job also the
SAMPLEs the client received against those recorded (it subscribes a moment after the agent starts sending, and
Foxglove attaches to the run's hub in the background: a run shorter than that attach sends it none). The
ratio is the medians' (with Foxglove / alone): below 1, Foxglove slows the job.
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from groundstation.mcap_io import read_recording  # noqa: E402
from tests.groundstation.foxglove_client import FoxgloveClient  # noqa: E402

DIVE = [sys.executable, "-m", "groundstation.cli.app"]


def _job(folder: Path, episodes: int, seed: int, foxglove: bool) -> tuple[float, int, int, float]:
    """(wall seconds, SAMPLEs the client received, SAMPLEs recorded, seconds they came over) of one `dive run`."""
    out = folder / ("fox" if foxglove else "alone")
    env = {**os.environ, "DIVE_RUNTIME_DIR": str(folder / "runtime"), "DIVE_CACHE_DIR": str(folder / "cache")}
    began = time.monotonic()
    proc = subprocess.Popen([*DIVE, "run", f"sim://?speed=max&seed={seed}", "--episodes", str(episodes),
                             "--out", str(out), *(["--foxglove", "0"] if foxglove else [])],
                            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    received = 0
    if foxglove:
        assert proc.stderr is not None
        port = int(re.search(r"ws://127\.0\.0\.1:(\d+)", proc.stderr.readline()).group(1))  # type: ignore[union-attr]
        with FoxgloveClient.connected(port) as client:
            subscribed: dict[str, int] = {}  # topic -> subscription id

            def subscribe_new() -> bool:
                for topic in [t for t in client.channels if t.startswith("/agent/") and t not in subscribed]:
                    subscribed[topic] = client.subscribe(topic)
                return proc.poll() is not None

            client.pump(subscribe_new, 600)
            received = len(client.messages.get(subscribed.get("/agent/SAMPLE", -1), []))
    threading.Thread(target=proc.communicate, daemon=True).start()  # drain stderr
    proc.wait(600)
    wall = time.monotonic() - began
    [recording] = sorted(out.glob("*.mcap"))
    times = [msg.log_time_ns for msg in read_recording(recording, {"/agent/SAMPLE"}).messages]
    streaming = (max(times) - min(times)) / 1e9  # the first SAMPLE to the last: the virtual agent's start left out
    return wall, received, len(times), streaming


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--seed", type=int, default=3)
    args = parser.parse_args()
    alone, fox = [], []
    with tempfile.TemporaryDirectory() as tmp:
        for r in range(args.rounds):
            folder = Path(tmp) / f"round{r}"
            a, _, a_samples, a_s = _job(folder, args.episodes, args.seed, False)
            f, got, f_samples, f_s = _job(folder, args.episodes, args.seed, True)
            alone.append(a_samples / a_s)
            fox.append(f_samples / f_s)
            print(f"round {r + 1}: alone {a:6.2f} s, {a_samples} SAMPLEs recorded ({alone[-1]:.0f}/s); with Foxglove "
                  f"{f:6.2f} s, {f_samples} recorded ({fox[-1]:.0f}/s), of which the client received {got}")
    print(f"median SAMPLEs per second while streaming: alone {statistics.median(alone):.0f}, with Foxglove "
          f"{statistics.median(fox):.0f}, ratio {statistics.median(fox) / statistics.median(alone):.2f}; "
          f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
