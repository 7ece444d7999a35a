"""How long the recovery controller takes to hand over on imperfect gears and sensors (issue 29; not a test).

    .venv/bin/python scripts/recovery_probe.py [--starts 8] [--seed 1] [--params recovery_near_gain_deg=0]

Each start is a real episode start of the compiled task (DivingEnv.reset, hardware preset) after 10-60 random
learner steps have pushed the agent off. Per plant it prints the recovery time's median and maximum, how many
starts gave up all 20 attempts, and the worst error of the handed-over neutral point.
"""

from __future__ import annotations

import argparse

import numpy as np
from rich.console import Console
from rich.table import Table

from learning.presets import learner_preset
from simulator.gym.task import DivingEnv
from simulator.parameters import neutral_alpha_deg, preset, with_overrides

PLANTS: tuple[dict[str, float], ...] = (
    {},
    {"backlash_deg": 1.0},
    {"backlash_deg": 2.0},
    {"backlash_deg": 3.0},
    {"dead_band_deg": 0.5},
    {"backlash_deg": 2.0, "dead_band_deg": 0.5},
    {"pressure_lag_s": 0.2},
    {"pressure_noise_pa": 13.0},
)
ALL_ATTEMPTS_S = 1999.0  # 20 attempts of 100 s: the start handed over unsettled


def probe(overrides: dict[str, float], starts: int, seed: int) -> tuple[float, float, int, float]:
    """(median recovery s, max recovery s, starts that gave up, worst |neutral error| deg)."""
    params = with_overrides(preset("hardware"), overrides)
    env = DivingEnv(params, learner_preset("hardware"))
    rng = np.random.default_rng(seed)
    env.reset(seed=seed)
    times, errors = [], []
    for _ in range(starts):
        for _ in range(int(rng.integers(10, 60))):
            *_, terminated, truncated, _ = env.step(int(rng.integers(2)))
            if terminated or truncated:
                break
        obs, info = env.reset()
        times.append(info["recovery_s"])
        errors.append(abs(info["alpha_cmd_deg"] - obs[2] - neutral_alpha_deg(params)))
    t = np.array(times)
    return float(np.median(t)), float(t.max()), int(np.sum(t >= ALL_ATTEMPTS_S)), max(errors)


def _override(text: str) -> tuple[str, float]:
    name, _, value = text.partition("=")
    return name.strip(), float(value)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--starts", type=int, default=8)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--params", type=_override, nargs="*", default=[], help="NAME=VALUE added to every plant")
    args = ap.parse_args()
    extra = dict(args.params)
    table = Table("plant", "median s", "max s", "gave up", "neutral error deg")
    for plant in PLANTS:
        median, longest, gave_up, error = probe({**plant, **extra}, args.starts, args.seed)
        label = ", ".join(f"{k} {v:g}" for k, v in {**plant, **extra}.items()) or "ideal"
        table.add_row(label, f"{median:.0f}", f"{longest:.0f}", f"{gave_up} / {args.starts}", f"{error:.2f}")
    Console().print(table)


if __name__ == "__main__":
    main()
