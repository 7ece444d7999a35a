"""The plant's step alone: 5 ms semi-implicit Euler sub-steps against their closed form (issue 43 item 4), CPU per
0.1 s control period under a chattering two-action command, the ideal gear and a gear train with backlash and dead
band; alternated, best of `--repeats`. The rule the closed form must keep is tests/simulator/plant/test_closed_form.py.

    .venv/bin/python benchmarks/closed_form_bench.py [--steps 1000000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.spec import KernelSpec
from simulator.parameters import PlantParams, kernel_params, preset, with_overrides
from simulator.plant.kernel import PLANT_SIZE, ZDOT, Z, plant_place, plant_step

PLANTS = {"ideal gear": {}, "backlash 1 deg, dead band 0.3 deg": {"backlash_deg": 1.0, "dead_band_deg": 0.3}}


@njit(cache=True)
def _periods(state: NDArray[np.float64], spec: KernelSpec, centre_deg: float, steps: int) -> float:
    """steps control periods of a command that steps 2.1 deg toward the target each period (the learner's kind)."""
    cmd = centre_deg
    for _ in range(steps):
        cmd += 2.1 if state[ZDOT] + 0.3 * (state[Z] - 0.4) > 0.0 else -2.1
        plant_step(state, cmd, 0.1, spec)
    return state[Z]


def _cpu_ns(params: PlantParams, steps: int) -> float:
    spec = kernel_params(params)
    state = np.zeros(PLANT_SIZE)
    plant_place(state, 0.4, 0.0, 66.0)
    start = time.process_time()
    _periods(state, spec, 66.0, steps)
    return (time.process_time() - start) / steps * 1e9


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    for name, overrides in PLANTS.items():
        sub = with_overrides(preset("hardware"), overrides)
        closed = dataclasses.replace(sub, closed_form_step=True)
        for params in (sub, closed):
            _cpu_ns(params, 10)  # compile or load the cache outside the timing
        times: dict[bool, list[float]] = {False: [], True: []}
        for _ in range(args.repeats):
            for params in (sub, closed):
                times[params.closed_form_step].append(_cpu_ns(params, args.steps))
        ref, fast = min(times[False]), min(times[True])
        print(f"{name}: sub-steps {ref:.0f} ns per control period, closed form {fast:.0f} ns: {ref / fast:.2f}x "
              f"(best of {args.repeats}, {args.steps} periods)")


if __name__ == "__main__":
    main()
