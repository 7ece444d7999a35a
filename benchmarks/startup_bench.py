"""Start-up time of `dive --help` and of every command's help, against the bare interpreter, in the same run.

Run: `.venv/bin/python benchmarks/startup_bench.py [--repeat 5]`. Not a test: it prints figures.
Goal (issue 14): every command starts in under 0.3 s (Rerun, numba, matplotlib, mcap imported only where used;
`python -X importtime -m groundstation.cli.app --help` shows what is). Wall time is the median of the runs; CPU
time (user + system) is printed beside it, since on a shared machine the wall time mostly measures the queue.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

COMMANDS = [["--help"], ["run", "-h"], ["view", "-h"], ["replay", "-h"], ["record", "-h"], ["status", "-h"],
            ["params", "-h"], ["surface", "-h"], ["hover", "-h"], ["dump", "-h"], ["mark", "-h"], ["check", "-h"],
            ["log", "info", "-h"], ["log", "export", "-h"], ["log", "recover", "-h"], ["keygen", "-h"]]


def _time(argv: list[str], repeat: int) -> tuple[float, float]:
    walls, cpus = [], []
    for _ in range(repeat):
        before = os.times()
        began = time.perf_counter()
        subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        walls.append(time.perf_counter() - began)
        after = os.times()
        cpus.append(after.children_user - before.children_user + after.children_system - before.children_system)
    return statistics.median(walls), statistics.median(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    anchor_wall, anchor_cpu = _time([sys.executable, "-c", "pass"], args.repeat)
    print(f"{'command':<22} {'wall s':>7} {'cpu s':>7} {'wall / python -c pass':>22}  goal 0.3 s")
    print(f"{'python -c pass':<22} {anchor_wall:7.3f} {anchor_cpu:7.3f} {1.0:21.1f}x")
    for command in COMMANDS:
        wall, cpu = _time([sys.executable, "-m", "groundstation.cli.app", *command], args.repeat)
        verdict = "ok" if wall < 0.3 else "over"
        print(f"{'dive ' + ' '.join(command):<22} {wall:7.3f} {cpu:7.3f} {wall / anchor_wall:21.1f}x  {verdict}")


if __name__ == "__main__":
    main()
