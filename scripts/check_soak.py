"""`dive check` N times against each of our conformant agents; prints the false failures per cell (not a test).

    nice -n 5 .venv/bin/python scripts/check_soak.py [-n 20] [--speeds max,1] [--firmwares python,c,qemu]
        [--pacings none,115200] [--key] [--jobs N]

Every run is a real `dive check sim://?...` (a fresh agent, its own seed) in a child process. The agents are
conformant, so every FAIL is a false failure of `dive check` (issue 26: the goal is 0 in 20 runs of each cell of
agent x speed x pacing). The QEMU build has no paced link (`dive sim --firmware qemu` refuses --baud: QEMU hands
the UART's bytes to its socket as fast as the firmware writes them), so its paced cells are left out.

A run at --speed 1 takes minutes of agent time and little CPU, so `--jobs N` runs N checks at once (each job its own
key file: a ground's replay mark must not be shared by two grounds signing at the same time).
"""

from __future__ import annotations

import argparse
import json
import signal
import subprocess
import sys
import tempfile
import threading
import time
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeElapsedColumn
from rich.table import Table

ROOT = Path(__file__).resolve().parent.parent
DIVE = "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"
RUN_TIMEOUT_S = 1800.0  # one whole check run at --speed 1 through RECOVERING takes minutes


@dataclass
class Tally:
    url: str
    agent: str
    speed: str
    pacing: str
    runs: int = 0
    passed: int = 0
    seconds: list[float] = field(default_factory=list)
    failures: Counter[str] = field(default_factory=Counter)
    details: list[str] = field(default_factory=list)


AGENTS = {"python": "Python virtual agent", "c": "C firmware, host build", "qemu": "C firmware on QEMU"}
UNPACED = "none"


def agent_url(firmware: str, speed: str, seed: int, pacing: str) -> str:
    query = [f"speed={speed}", f"seed={seed}"] + ([f"firmware={firmware}"] if firmware != "python" else [])
    return "sim://?" + "&".join(query + ([f"baud={pacing}"] if pacing != UNPACED else []))


def cells(firmwares: str, speeds: str, pacings: str) -> list[tuple[str, str, str]]:
    """Every (agent, speed, pacing) asked for that the agent can do; a bad name is one line and exit 2."""
    chosen = [(fw, speed, pacing) for fw in firmwares.split(",") for speed in speeds.split(",")
              for pacing in pacings.split(",")]
    for fw, _, pacing in chosen:
        if fw not in AGENTS:
            raise SystemExit(f"check_soak: no agent {fw!r} (choose from {', '.join(AGENTS)})")
        if pacing != UNPACED and not pacing.isdigit():
            raise SystemExit(f"check_soak: pacing {pacing!r} is neither {UNPACED!r} nor a baud rate")
    return [(fw, speed, pacing) for fw, speed, pacing in chosen if not (fw == "qemu" and pacing != UNPACED)]


RUNNING: set[subprocess.Popen[str]] = set()  # the checks under way, killed when the soak is stopped
RUNNING_LOCK = threading.Lock()


def run_once(url: str, key_file: Path | None) -> tuple[bool, float, list[tuple[str, str]]]:
    """One `dive check URL --json`: (passed, seconds, [(check id, detail) of each FAIL])."""
    args = [sys.executable, "-c", DIVE, "check", url, "--json", "--allow-motion"]
    if key_file is not None:
        args += ["--key-file", str(key_file)]
    started = time.monotonic()
    child = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    with RUNNING_LOCK:
        RUNNING.add(child)
    try:
        stdout, stderr = child.communicate(timeout=RUN_TIMEOUT_S)
    except subprocess.TimeoutExpired:
        child.kill()
        child.communicate()
        return False, time.monotonic() - started, [("(run)", f"no report within {RUN_TIMEOUT_S:g} s")]
    finally:
        with RUNNING_LOCK:
            RUNNING.discard(child)
    took = time.monotonic() - started
    try:
        report = json.loads(stdout)
    except json.JSONDecodeError:
        last = (stderr.strip().splitlines() or ["no output"])[-1]
        return False, took, [("(run)", last)]
    fails = [(c["id"], c["detail"]) for c in report["checks"] if c["result"] == "FAIL"]
    if report.get("aborted"):
        fails.append(("(aborted)", report["aborted"]))
    return not fails, took, fails


def soak(grid: list[tuple[str, str, str]], tallies: dict[tuple[str, str, str], Tally], runs: int, seed: int,
         key_files: list[Path | None], bar: Progress, task: TaskID) -> None:
    """`runs` rounds over the grid, each cell once a round, one job per key file; every run's outcome into its
    cell's tally. Ctrl-C or SIGTERM kills the runs under way (dropped from the tally) and returns."""
    queue = [(cell, seed + k) for k in range(runs) for cell in grid]  # interleaved: a load spike hits every cell
    lock = threading.Lock()
    stopping = threading.Event()

    def job(key_file: Path | None) -> None:
        while not stopping.is_set():
            with lock:
                if not queue:
                    return
                cell, run_seed = queue.pop(0)
            url = agent_url(cell[0], cell[1], run_seed, cell[2])
            passed, took, fails = run_once(url, key_file)
            if stopping.is_set():
                return  # killed by the stop: not an outcome of the agent
            with lock:
                tally = tallies[cell]
                tally.runs += 1
                tally.passed += passed
                tally.seconds.append(took)
                for check_id, detail in fails:
                    tally.failures[check_id] += 1
                    tally.details.append(f"{url}: {check_id}: {detail}")
                said = "passed" if passed else "FAILED " + "; ".join(f"{c}: {d}" for c, d in fails)
                bar.console.print(f"{url}: {said} in {took:.0f} s", markup=False, highlight=False)
                bar.advance(task)

    workers = [threading.Thread(target=job, args=(key_file,), daemon=True) for key_file in key_files]
    for worker in workers:
        worker.start()
    try:
        for worker in workers:
            while worker.is_alive():
                worker.join(0.5)  # a timed join: the main thread must stay able to take SIGINT / SIGTERM
    except KeyboardInterrupt:
        stopping.set()
        with RUNNING_LOCK:
            for child in RUNNING:
                child.kill()
        raise


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", "--runs", type=int, default=20, help="runs per cell (default 20)")
    parser.add_argument("--speeds", default="max,1", help="comma-separated --speed values (default max,1)")
    parser.add_argument("--firmwares", default="python,c,qemu", help="python, c, qemu (default all three)")
    parser.add_argument("--pacings", default="none,115200",
                        help="comma-separated: none (unpaced) or a baud rate (default none,115200)")
    parser.add_argument("--key", action="store_true", help="give every agent a key (the signing checks run too)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the first run; run k uses seed + k")
    parser.add_argument("--jobs", type=int, default=1, help="checks run at once (default 1)")
    args = parser.parse_args()
    console = Console()
    grid = cells(args.firmwares, args.speeds, args.pacings)
    interrupted = False
    tallies = {cell: Tally(agent_url(cell[0], cell[1], 0, cell[2]), *cell) for cell in grid}
    with tempfile.TemporaryDirectory() as tmp:
        key_files: list[Path | None] = [None] * max(1, args.jobs)
        if args.key:
            from groundstation.session.keys import write_key_file

            key_files = [write_key_file(Path(tmp) / f"soak-{j}.key") for j in range(len(key_files))]
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      console=console) as bar:
            task = bar.add_task("dive check", total=len(grid) * args.runs)
            # SIGTERM too (`kill PID`: a soak run in the background, where SIGINT is ignored) ends it with the table
            signal.signal(signal.SIGINT, signal.default_int_handler)
            signal.signal(signal.SIGTERM, signal.default_int_handler)
            try:
                soak(grid, tallies, args.runs, args.seed, key_files, bar, task)
            except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the table of the runs that ended, the run under way dropped
                interrupted = True
    title = f"dive check x {args.runs} per cell" + (", keyed" if args.key else "")
    table = Table(title=title + (f" (interrupted after {sum(t.runs for t in tallies.values())} runs)"
                                 if interrupted else ""))
    for column in ("agent", "speed", "pacing", "runs", "passes", "false failures", "checks that failed",
                   "s per run (median)"):
        table.add_column(column)
    for tally in tallies.values():
        median = sorted(tally.seconds)[len(tally.seconds) // 2] if tally.seconds else 0.0
        failed = ", ".join(f"{c} x{n}" for c, n in tally.failures.most_common()) or "-"
        pacing = tally.pacing if tally.pacing == UNPACED else f"{tally.pacing} baud"
        table.add_row(AGENTS[tally.agent], tally.speed, pacing, str(tally.runs), str(tally.passed),
                      str(sum(tally.failures.values())), failed, f"{median:.0f}")
    console.print(table)
    if "qemu" in args.firmwares.split(",") and any(p != UNPACED for p in args.pacings.split(",")):
        console.print("C firmware on QEMU, paced: not run (QEMU does not pace its UART; dive sim --firmware qemu "
                      "refuses --baud)", markup=False, highlight=False)
    for line in [d for t in tallies.values() for d in t.details]:
        console.print(line, markup=False, highlight=False)
    raise SystemExit(0 if all(t.passed == t.runs for t in tallies.values()) else 1)


if __name__ == "__main__":
    main()
