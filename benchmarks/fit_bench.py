"""`dive fit` at size (issue 30): ten minutes of 40 Hz agent time fitted, goal under 30 s on the 2-core machine.

    PYTHONPATH=. .venv/bin/python benchmarks/fit_bench.py [--minutes 10] [--seed 30]

Records the virtual agent (`dive run`, hardware preset, speed max) on a plant drawn as the hidden-truth test draws
it until the recordings hold the minutes asked for in fit windows, then times the whole fit (read, windows, fit).
The anchors, measured in the same run: reading the recordings alone (the mcap library), and one run of the
compiled plant over every window; the fit is printed as a multiple of each.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from simulator.fit.estimate import fit_recordings, sensor_depth_limit_m
from simulator.fit.model import simulate, start_states
from simulator.fit.reader import read_samples
from simulator.fit.windows import cut_windows
from simulator.parameters import preset
from tests.simulator.fit.truth import draw_truth, record, write_plant


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=10.0)
    parser.add_argument("--seed", type=int, default=30)
    args = parser.parse_args()
    base = preset("hardware")
    with tempfile.TemporaryDirectory() as folder:
        truth = draw_truth(args.seed)
        plant = write_plant(Path(folder) / "truth.toml", truth)
        files: list[Path] = []
        seconds = 0.0
        began = time.perf_counter()
        while seconds < 60.0 * args.minutes:
            files.append(record(plant, Path(folder) / f"rec{len(files)}", seed=args.seed + len(files), episodes=8))
            windows = cut_windows(read_samples(files), 10.0, sensor_depth_limit_m(base))
            seconds = windows.seconds
        print(f"recorded {len(files)} runs in {time.perf_counter() - began:.0f} s: {seconds:.0f} s of agent time "
              f"in {windows.count} windows, {len(windows.t_s)} samples; load average {os.getloadavg()[0]:.1f}")
        started = time.perf_counter()
        samples = read_samples(files)
        read_s = time.perf_counter() - started
        z0, v0 = start_states(windows)
        simulate(base, windows, z0, v0)
        started = time.perf_counter()
        repeats = 20
        for _ in range(repeats):
            simulate(base, windows, z0, v0)
        plant_run_s = (time.perf_counter() - started) / repeats
        started = time.perf_counter()
        result = fit_recordings(files, base)
        fit_s = time.perf_counter() - started
    print(f"fit of {result.windows.seconds / 60:.1f} min ({len(samples.t_s)} samples read): {fit_s:.1f} s wall "
          f"(goal 30 s: {fit_s / 30.0:.2f} of it); load average {os.getloadavg()[0]:.1f}")
    print(f"anchor: reading alone {read_s:.1f} s (the fit is {fit_s / read_s:.1f} x); one run of the compiled "
          f"plant over every window {1000 * plant_run_s:.1f} ms (the fit is {fit_s / plant_run_s:.0f} runs)")
    print(f"residual RMS {1000 * result.residual_rms_m:.3f} mm; fitted against the drawn truth:")
    for name, value in truth.items():
        e = result.estimate(name)
        print(f"  {name:22} truth {value:.6g}, fit {e.value:.6g} +/- {e.half_width:.3g} (95 %), "
              f"error {100 * (e.value - value) / value:+.2f} %")


if __name__ == "__main__":
    main()
