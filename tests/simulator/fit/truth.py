"""A hidden plant drawn from the documented ranges, and recordings of the virtual agent flying it (`dive run`)."""

from __future__ import annotations

from pathlib import Path
from typing import Any
from urllib.parse import quote

import numpy as np

from groundstation.recording.recorder import RecorderConfig
from groundstation.run.job import RunConfig, run

SEED = 30  # the fit's issue number: a fixed draw, the same on every machine
QEMU_SEED = 31  # the C firmware on QEMU flies a plant of its own draw

# diving-agent.md s. 1 and simulator/parameters.py: added mass 0.06-0.15 kg (estimate), drag k 1-1.7 kg/m
# (authors' 1, textbook 1.7), trim error 0.5-1 % of V0 (DICE; positive: an idle agent floats at the surface
# instead of resting on the floor, out of the sensor's range), the stepper's 35.2 deg/s +/- 10 %, the sensor's
# noise between OSR 4096 (1.2 Pa) and OSR 256 (6.5 Pa). Compressibility has no documented range: up to a
# thousandth of V0 per 3 m, our choice.
RANGES: dict[str, tuple[float, float]] = {
    "added_mass_kg": (0.06, 0.15),
    "drag_kgpm": (1.0, 1.7),
    "trim_error_fraction": (0.005, 0.01),
    "compressibility_m3pm": (0.0, 1.2e-7),
    "alpha_rate_dps": (31.7, 38.7),
    "pressure_noise_pa": (1.2, 6.5),
}


def draw_truth(seed: int = SEED) -> dict[str, float]:
    rng = np.random.default_rng(seed)
    return {name: float(rng.uniform(low, high)) for name, (low, high) in RANGES.items()}


def write_plant(path: Path, figures: dict[str, Any]) -> Path:
    """A plant file as `dive fit` writes them: a [plant] table."""
    path.write_text("[plant]\n" + "".join(f"{name} = {value!r}\n" for name, value in figures.items()))
    return path


def record(plant_file: Path, out: Path, seed: int, episodes: int = 3) -> Path:
    """One `dive run` of the virtual agent (hardware preset, the observer in the loop) on the plant file."""
    url = f"sim://?speed=max&seed={seed}&preset=hardware&params={quote(str(plant_file))}"
    result = run(RunConfig(url=url, episodes=episodes, recorder=RecorderConfig(directory=out)))
    assert len(result.paths) == 1
    return result.paths[0]
