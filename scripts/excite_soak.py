"""`dive fit --excite`'s manoeuvre N times against a fresh agent; prints how far each dive overran (not a test).

    .venv/bin/python scripts/excite_soak.py [-n 4] [--url "sim://?firmware=qemu&speed=max"] [--hold 30]

Each run flies the manoeuvre (groundstation/run/excite.py) and reads its recording back. Its dive lasts
len(depths) x hold of agent time plus what the agent ran ahead of the ground at each command (what the link
buffered while the ground was slow); past the agent's max_dive_s it surfaces by itself and the run fails
(issue 30's bug: 2 of 4 runs at load 10-14). Run it beside a busy loop on every core to see it under load.
"""

from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from groundstation.errors import GroundStationError
from groundstation.mcap_io.reader import iter_topic_data
from groundstation.recording.recorder import RecorderConfig
from groundstation.recording.tables import SAMPLE_TOPIC
from groundstation.run.excite import ExciteConfig, excite
from protocol import Mode


def dive_agent_s(paths: list[Path]) -> float:
    """Agent seconds from the first HOVER sample to the first SURFACING one (live samples, every part)."""
    first_hover = first_surfacing = last_hover = None
    for path in paths:
        for _, _, data in iter_topic_data(path, {SAMPLE_TOPIC}):
            body = json.loads(data)
            if body.get("_backfilled"):
                continue
            if body["mode"] == Mode.HOVER:
                first_hover = body["t_us"] if first_hover is None else first_hover
                last_hover = body["t_us"]
            elif body["mode"] == Mode.SURFACING and first_hover is not None and first_surfacing is None:
                first_surfacing = body["t_us"]
    if first_hover is None:
        return float("nan")
    # No SURFACING sample arrived before the link closed (the agent that far ahead): at least the last HOVER one.
    end = first_surfacing if first_surfacing is not None else (last_hover or first_hover)
    return (end - first_hover) / 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("-n", "--runs", type=int, default=4)
    parser.add_argument("--url", default="sim://?firmware=qemu&speed=max")
    parser.add_argument("--hold", type=float, default=30.0, help="agent seconds at each depth (default 30)")
    args = parser.parse_args()
    console = Console()
    passed = 0
    with tempfile.TemporaryDirectory() as tmp, Progress(
            TextColumn("excite"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(), console=console) as bar:
        task = bar.add_task("", total=args.runs)
        for run in range(args.runs):
            config = ExciteConfig(url=args.url, hold_s=args.hold,
                                  recorder=RecorderConfig(directory=Path(tmp) / str(run)))
            planned = len(config.depths_m) * config.hold_s
            load = os.getloadavg()[0]
            began = time.monotonic()
            try:
                paths, outcome = excite(config), "pass"
                passed += 1
            except GroundStationError as e:
                paths, outcome = sorted((Path(tmp) / str(run)).rglob("*.mcap")), f"FAIL: {e}"
            dived = dive_agent_s(paths) if paths else float("nan")
            bar.console.print(f"run {run + 1}: {time.monotonic() - began:.0f} s wall, load {load:.1f}, dive "
                              f"{dived:.1f} s of agent time for {planned:g} planned (over by {dived - planned:.1f}; "
                              f"max_dive_s {config.max_dive_s:g}): {outcome}")
            bar.advance(task)
    console.print(f"{passed} of {args.runs} passed ({args.url})")


if __name__ == "__main__":
    main()
