"""`dive check` N times against each of our conformant agents; prints the false failures per agent (not a test).

    .venv/bin/python scripts/check_soak.py [-n 20] [--speeds max,1] [--firmwares python,c] [--baud 115200] [--key]

Every run is a real `dive check sim://?...` (a fresh virtual agent, its own seed) in a child process. The agents are
conformant, so every FAIL is a false failure of `dive check` (issue 26: the goal is 0 in 20 runs of each).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
DIVE = "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"
RUN_TIMEOUT_S = 1800.0  # one whole check run at --speed 1 through RECOVERING takes minutes


@dataclass
class Tally:
    url: str
    runs: int = 0
    passed: int = 0
    seconds: list[float] = field(default_factory=list)
    failures: Counter[str] = field(default_factory=Counter)
    details: list[str] = field(default_factory=list)


def agent_url(firmware: str, speed: str, seed: int, baud: int | None) -> str:
    query = [f"speed={speed}", f"seed={seed}"] + ([f"firmware={firmware}"] if firmware != "python" else [])
    return "sim://?" + "&".join(query + ([f"baud={baud}"] if baud else []))


def run_once(url: str, key_file: Path | None) -> tuple[bool, float, list[tuple[str, str]]]:
    """One `dive check URL --json`: (passed, seconds, [(check id, detail) of each FAIL])."""
    args = [sys.executable, "-c", DIVE, "check", url, "--json", "--allow-motion"]
    if key_file is not None:
        args += ["--key-file", str(key_file)]
    started = time.monotonic()
    try:
        done = subprocess.run(args, capture_output=True, text=True, cwd=ROOT, timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return False, time.monotonic() - started, [("(run)", f"no report within {RUN_TIMEOUT_S:g} s")]
    took = time.monotonic() - started
    try:
        report = json.loads(done.stdout)
    except json.JSONDecodeError:
        last = (done.stderr.strip().splitlines() or ["no output"])[-1]
        return False, took, [("(run)", last)]
    fails = [(c["id"], c["detail"]) for c in report["checks"] if c["result"] == "FAIL"]
    if report.get("aborted"):
        fails.append(("(aborted)", report["aborted"]))
    return not fails, took, fails


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", "--runs", type=int, default=20, help="runs per agent (default 20)")
    parser.add_argument("--speeds", default="max,1", help="comma-separated --speed values (default max,1)")
    parser.add_argument("--firmwares", default="python,c", help="python, c (default both)")
    parser.add_argument("--baud", type=int, default=None, help="pace every agent's link at this baud rate")
    parser.add_argument("--key", action="store_true", help="give every agent a key (the signing checks run too)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the first run; run k uses seed + k")
    args = parser.parse_args()
    console = Console()
    agents = [(fw, speed) for fw in args.firmwares.split(",") for speed in args.speeds.split(",")]
    tallies: dict[tuple[str, str], Tally] = {}
    with tempfile.TemporaryDirectory() as tmp:
        key_file = None
        if args.key:
            from groundstation.session.keys import write_key_file

            key_file = write_key_file(Path(tmp) / "soak.key")
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      console=console) as bar:
            task = bar.add_task("dive check", total=len(agents) * args.runs)
            for k in range(args.runs):
                for fw, speed in agents:  # interleaved: a load spike hits every agent alike
                    url = agent_url(fw, speed, args.seed + k, args.baud)
                    tally = tallies.setdefault((fw, speed), Tally(agent_url(fw, speed, 0, args.baud)))
                    bar.update(task, description=url)
                    passed, took, fails = run_once(url, key_file)
                    tally.runs += 1
                    tally.passed += passed
                    tally.seconds.append(took)
                    for check_id, detail in fails:
                        tally.failures[check_id] += 1
                        tally.details.append(f"{url}: {check_id}: {detail}")
                    bar.console.print(f"{url}: {'passed' if passed else 'FAILED ' + ', '.join(c for c, _ in fails)}"
                                      f" in {took:.0f} s", markup=False, highlight=False)
                    bar.advance(task)
    table = Table(title=f"dive check x {args.runs} per agent" + (f", {args.baud} baud" if args.baud else "")
                  + (", keyed" if args.key else ""))
    for column in ("agent", "runs passed", "false failures", "checks that failed", "s per run (median)"):
        table.add_column(column)
    for tally in tallies.values():
        median = sorted(tally.seconds)[len(tally.seconds) // 2]
        failed = ", ".join(f"{c} x{n}" for c, n in tally.failures.most_common()) or "-"
        table.add_row(tally.url.replace("seed=0&", "").replace("&seed=0", ""), f"{tally.passed}/{tally.runs}",
                      str(sum(tally.failures.values())), failed, f"{median:.0f}")
    console.print(table)
    for line in [d for t in tallies.values() for d in t.details]:
        console.print(line, markup=False, highlight=False)
    raise SystemExit(0 if all(t.passed == t.runs for t in tallies.values()) else 1)


if __name__ == "__main__":
    main()
