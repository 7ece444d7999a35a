"""Screen velocity-filter variants of the hardware learner: never-stable trials per plant and region (issue 29).

    python scripts/screen_filters.py --variants base,t85zst,t90zst --plants noise2,combined,tank,lag0.2 --seed 12

Each line is one study of --trials trials x 400 episodes (JSON): never stable (a failure in the last 50 episodes),
late failures (failed episodes among the last 100) and the median first success. docs/learners.md, "The
`hardware` learner, ingredient by ingredient", sums them per variant.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np

from learning import learner_preset
from simulator.parameters import PlantParams, load_params, preset
from simulator.study.family import load_family
from simulator.study.runner import run_study

BASE = "shared-z20-bins7-filter-term100-vpen1"
PLANTS = {"modelled": "", "noise2": "docs/perturbations/noise2.toml", "combined": "docs/perturbations/combined.toml",
          "lag0.2": "docs/perturbations/lag0.2.toml", "trim-3": "docs/perturbations/trim-3.toml",
          "tank": "docs/families/tank.toml"}
REGIONS = ((0.1, 0.04), (0.15, 0.03))


def fading_memory_gains(theta: float) -> dict[str, float]:
    """The g-h-k gains of the fading-memory filter at theta (learning/presets.py writes them out as decimals)."""
    return {"filter_depth_gain": 1 - theta**3, "filter_velocity_gain": 1.5 * (1 - theta**2) * (1 - theta),
            "filter_bias_gain": (1 - theta) ** 3 / 2}


VARIANTS: dict[str, dict[str, Any]] = {
    "base": {},
    "zst": {"filter_depth_state": True},
    "t85": fading_memory_gains(0.85),
    "t85zst": {**fading_memory_gains(0.85), "filter_depth_state": True},
    "t90zst": {**fading_memory_gains(0.90), "filter_depth_state": True},
}


def plants_of(name: str, trials: int, seed: int) -> tuple[PlantParams, list[PlantParams] | None]:
    base = preset("hardware")
    path = PLANTS[name]
    if name == "tank":
        family = load_family(Path(path), base)
        return base, [family.draw(base, seed, t) for t in range(trials)]
    return (load_params(Path(path), base) if path else base), None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--variants", default="base,t90zst", help=f"comma-separated, of {', '.join(VARIANTS)}")
    ap.add_argument("--plants", default="noise2,combined", help=f"comma-separated, of {', '.join(PLANTS)}")
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--trials", type=int, default=100)
    args = ap.parse_args()
    for plant in args.plants.split(","):
        params, plants = plants_of(plant, args.trials, args.seed)
        for z_tol, zdot_tol in REGIONS:
            for variant in args.variants.split(","):
                config = learner_preset(BASE, z_tol_m=z_tol, zdot_tol_mps=zdot_tol, **VARIANTS[variant])
                start = time.time()
                ok = run_study(params, config, args.trials, 400, seed=args.seed, plants=plants).durations_s >= 299.999
                first = [int(np.argmax(row)) if row.any() else 400 for row in ok]
                print(json.dumps({"plant": plant, "region": [z_tol, zdot_tol], "variant": variant,
                                  "never": int((~ok[:, -50:]).any(axis=1).sum()), "late": int((~ok[:, -100:]).sum()),
                                  "first": float(np.median(first)), "trials": args.trials, "seed": args.seed,
                                  "wall_s": round(time.time() - start)}), flush=True)


if __name__ == "__main__":
    main()
