"""A newcomer's first `dive run`: the virtual agent's first HELLO and first episode on a cold compile cache, against the
same run on the cache it left (the anchor), in the same run of this script.

Run: `.venv/bin/python benchmarks/cold_start_bench.py [--episodes 2] [--url "sim://?seed=3&speed=max"]`. Not a test:
it prints figures. Each `dive run` gets NUMBA_CACHE_DIR set to one fresh folder: the first run compiles every kernel
(the agent's, and the ground's fast frame codec), the second loads them. Times are from the `dive run` process's
start to the first HELLO, the first command answered BUSY (the agent still building its program), the first SAMPLE
(the program runs) and the first EPISODE_END, each read back from the recording (its log times), with the machine's
load beside them: on a shared machine the wall time mostly measures the queue. Goal (SPEC.md s. 4, issue 39): the
first HELLO within seconds of the start whatever the cache, and the run waiting, never failing, while it compiles.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from mcap.reader import make_reader

DIVE = [sys.executable, "-c", "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"]
MARKS = (("first HELLO", "/agent/HELLO"), ("first BUSY", "busy"), ("first SAMPLE", "/agent/SAMPLE"),
         ("first EPISODE_END", "/agent/EPISODE_END"))


def _run(url: str, episodes: int, cache: Path, out: Path) -> dict[str, float]:
    """One `dive run`: seconds from its start to each of MARKS (absent: not reached), and to its end."""
    started_ns = time.time_ns()
    done = subprocess.run([*DIVE, "run", url, "--episodes", str(episodes), "--viewer", "none", "--out", str(out)],
                          capture_output=True, text=True, env={**os.environ, "NUMBA_CACHE_DIR": str(cache)},
                          check=False)
    seconds = {"end": (time.time_ns() - started_ns) / 1e9}
    if done.returncode != 0:
        print(f"dive run exited {done.returncode}: {done.stderr.strip().splitlines()[-1:]}")
    first: dict[str, int] = {}
    with out.open("rb") as f:
        for _, channel, message in make_reader(f).iter_messages(log_time_order=True):
            key = "busy" if channel.topic == "/event" and b'"agent_busy"' in message.data else channel.topic
            first.setdefault(key, message.log_time)
    for name, key in MARKS:
        if key in first:
            seconds[name] = (first[key] - started_ns) / 1e9
    return seconds


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--url", default="sim://?seed=3&speed=max")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as folder:
        cache = Path(folder) / "numba-cache"
        cache.mkdir()
        load_before = os.getloadavg()[0]
        cold = _run(args.url, args.episodes, cache, Path(folder) / "cold.mcap")
        warm = _run(args.url, args.episodes, cache, Path(folder) / "warm.mcap")
        load_after = os.getloadavg()[0]
    print(f"{args.url}, {args.episodes} episodes; load average {load_before:.1f} before, {load_after:.1f} after")
    print(f"{'seconds from the start to':<22} {'cold cache':>10} {'warm (anchor)':>14} {'cold / warm':>12}")
    for name in [*(n for n, _ in MARKS), "end"]:
        c, w = cold.get(name), warm.get(name)
        ratio = f"{c / w:11.1f}x" if c is not None and w else f"{'-':>12}"
        print(f"{name:<22} {_s(c):>10} {_s(w):>14} {ratio}")


def _s(seconds: float | None) -> str:
    return "-" if seconds is None else f"{seconds:.1f}"


if __name__ == "__main__":
    main()
