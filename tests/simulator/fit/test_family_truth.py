"""The fit against hidden plants of the whole tank family (issue 42): docs/families/tank.toml's draws with every
imperfection on (backlash, dead band, pressure lag, bias, drift, AR(1) noise, depth-scale error, jitter), flown by
the virtual agent and by the C firmware on QEMU with `dive fit --excite`'s manoeuvre, fitted from the hardware
preset. benchmarks/fit_family_bench.py runs more draws for the coverage figure."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from groundstation.recording.recorder import RecorderConfig
from groundstation.run.excite import ExciteConfig, excite
from simulator.fit.estimate import fit_recordings
from simulator.parameters import load_params, preset
from tests.simulator.fit.truth import Judged, draw_family, excite_url, judge, write_plant

pytestmark = pytest.mark.slow

DRAWS = (0, 1)
# What every draw must identify: the hull, the actuator, the gear's play, the port's lag and the noise.
MUST_IDENTIFY = ("added_mass_kg", "drag_kgpm", "alpha_rate_dps", "dead_band_deg", "backlash_deg", "pressure_lag_s",
                 "pressure_noise_pa", "neutral_angle_deg")
COVERAGE = 0.8  # of some 22 figures a 95 % interval misses more than 4 in 250 runs; the benchmark checks 90 %


def _fit_draw(agent: str, draw: int, folder: Path) -> list[Judged]:
    """One drawn plant flown and fitted; each figure checked against the issue's rules; the judged figures."""
    figures = draw_family(draw)
    plant_file = write_plant(folder / "truth.toml", figures)
    recorded = excite(ExciteConfig(url=excite_url(agent, plant_file, 100 + draw), hold_s=20.0,
                                   recorder=RecorderConfig(directory=folder / "rec")))
    fit = fit_recordings(recorded, preset("hardware"))
    truth = load_params(plant_file, preset("hardware"))
    judged = judge(fit.estimates, truth)
    names = {j.name for j in judged}
    assert set(MUST_IDENTIFY) <= names, f"draw {draw}: not identified: {set(MUST_IDENTIFY) - names}"
    for j in judged:
        # Issue 42's rule: never "identified" with an interval its error exceeds 3-fold.
        assert abs(j.error) <= 3.0 * j.half_width, f"draw {draw}: {j.name} {j.value} vs {j.truth} +/- {j.half_width}"
        goal = j.goal
        if j.name == "added_mass_kg":
            # A depth read (1 + s) too large is a hull (1 + s) lighter: the drawn scale error's share is no fit's
            # to remove (the interval admits it, the 5 % goal cannot).
            goal += abs(truth.depth_scale_error) * (truth.mass_kg + truth.added_mass_kg)
        assert abs(j.error) <= goal, f"draw {draw}: {j.name} {j.value} vs {j.truth}, goal {goal}"
    # The sensor's bias, drift and scale are named as not identifiable, with what would identify them.
    for name in ("pressure_bias_pa", "pressure_drift_pa_per_s", "depth_scale_error"):
        assert "not identifiable from these recordings, needs" in fit.estimate(name).needs
    return judged


@pytest.mark.parametrize("agent", ["python", "qemu"])
def test_drawn_plants_with_every_imperfection_are_fitted_within_the_goals_and_intervals(agent: str,
                                                                                        tmp_path: Path) -> None:
    if agent == "qemu":
        for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
            if shutil.which(tool) is None:
                pytest.skip(f"{tool} not found: the QEMU tests need it")
    judged: list[Judged] = []
    for draw in DRAWS:
        (tmp_path / str(draw)).mkdir()
        judged += _fit_draw(agent, draw, tmp_path / str(draw))
    inside = sum(j.inside for j in judged) / len(judged)
    outside = [f"{j.name} {j.value:.4g} vs {j.truth:.4g} +/- {j.half_width:.3g}" for j in judged if not j.inside]
    assert inside >= COVERAGE, f"{100 * inside:.0f} % inside their 95 % intervals: {outside}"
