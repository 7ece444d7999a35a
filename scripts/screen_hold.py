"""Screen learner variants for issue 43: learning goals (point estimates) and the hold (oscillation about the mean,
offset, travel) beside the recovery controller's, one line per variant; small studies to choose, not to report.

    .venv/bin/python scripts/screen_hold.py '{"name": {"fine_step_deg": 0.7, "fine_speed_mps": 0.016}}' \\
        --trials 16 --episodes 200 --seed 11 [--preset hardware-fast] [--family docs/families/tank.toml]

Each variant is BASE (the filtered-depth learner, `hardware` until issue 43 made it plan on growth) with the given
LearnerConfig fields replaced (docs/learners-hold.md).
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

from learning import learner_preset
from simulator.parameters import preset
from simulator.study.family import load_family
from simulator.study.hold import hold_summary
from simulator.study.runner import run_study
from simulator.study.stats import summarise

# The learner every variant starts from: `hardware` before issue 43 made it plan on growth (the screens' base).
BASE = "shared-z20-bins7-fdepth-term100-vpen1"


def screen(name: str, preset_name: str, overrides: dict[str, Any], trials: int, episodes: int, seed: int,
           family: Path | None) -> str:
    """One variant's line."""
    params = preset(preset_name)
    config = learner_preset(BASE, **overrides)
    plants = None
    if family is not None:
        drawn = load_family(family, params)
        plants = [drawn.draw(params, seed, t) for t in range(trials)]
    began = time.time()
    result = run_study(params, config, trials, episodes, seed, plants=plants)
    assert result.hold is not None
    summary = summarise(result.durations_s, params.episode_limit_s, 0)
    hold = hold_summary(result.hold, result.recovery_hold)
    across, own = summary["across_trials"], summary["across_trials"]["alc_stable_from"]
    mine, rec = hold["learner"], hold["recovery"]

    def q(block: dict[str, Any], key: str) -> str:
        return f"{block[key]['median']} [{block[key]['q25']}-{block[key]['q75']}]"

    return (f"{name:38s} first {across['first_success']['median']} ALC "
            f"{summary['alc_curves']['median']['stable_from']} own {own['median']} never {own['count_never']}/{trials}"
            f" | oscillation {q(mine, 'oscillation_rms_mm')} offset {mine['offset_mm']['median']} "
            f"p2p {mine['peak_to_peak_mm']['median']} travel {mine['actuator_travel_deg_per_min']['median']} "
            f"| controller oscillation {rec['oscillation_rms_mm']['median']} offset {rec['offset_mm']['median']} "
            f"travel {rec['actuator_travel_deg_per_min']['median']} [{time.time() - began:.0f} s]")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("variants", help="JSON: {name: {LearnerConfig field: value}}")
    parser.add_argument("--trials", type=int, default=16)
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--preset", default="hardware-fast")
    parser.add_argument("--family", type=Path, default=None)
    args = parser.parse_args()
    for name, overrides in json.loads(args.variants).items():
        print(screen(name, args.preset, overrides, args.trials, args.episodes, args.seed, args.family), flush=True)


if __name__ == "__main__":
    main()
