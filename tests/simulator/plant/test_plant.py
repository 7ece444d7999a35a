"""Physics a user would check: hover, sink, terminal velocity, step-size convergence, the surface."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from simulator.parameters import neutral_alpha_deg, preset
from simulator.plant.model import Plant

PARAMS = preset("paper")


def _plant(alpha_deg: float, depth_m: float = 1.0, params=PARAMS) -> Plant:
    plant = Plant(params, np.random.default_rng(0))
    plant.set_state(depth_m=depth_m, velocity_mps=0.0, alpha_deg=alpha_deg, alpha_cmd_deg=alpha_deg)
    return plant


def test_neutral_trim_hovers() -> None:
    plant = _plant(neutral_alpha_deg(PARAMS))
    for _ in range(600):
        plant.step(0.1)
    assert abs(plant.depth_m - 1.0) < 1e-6 and abs(plant.velocity_mps) < 1e-9


def test_less_volume_sinks_and_more_volume_rises() -> None:
    sinking = _plant(neutral_alpha_deg(PARAMS) - 10.0)
    rising = _plant(neutral_alpha_deg(PARAMS) + 10.0)
    for _ in range(100):
        sinking.step(0.1)
        rising.step(0.1)
    assert sinking.depth_m > 1.05 and sinking.velocity_mps > 0
    assert rising.depth_m < 0.95 and rising.velocity_mps < 0


def test_terminal_velocity_matches_the_drag_law() -> None:
    plant = _plant(0.0, depth_m=0.5)  # all adjustable volume out: half the stroke below neutral
    for _ in range(200):
        plant.step(0.1)
    net_force_n = PARAMS.water_density_kgpm3 * PARAMS.gravity_mps2 * PARAMS.stroke_volume_m3 / 2
    expected_mps = np.sqrt(net_force_n / PARAMS.drag_kgpm)
    assert plant.velocity_mps == pytest.approx(expected_mps, rel=1e-3)


def test_halving_the_integration_step_changes_a_60s_trajectory_by_under_1mm() -> None:
    def trajectory(substep_s: float) -> np.ndarray:
        plant = _plant(neutral_alpha_deg(PARAMS), params=replace(PARAMS, substep_s=substep_s))
        depths = []
        for k in range(600):
            # A bang-bang command like the learner's keeps the actuator and the hull moving.
            plant.alpha_cmd_deg = neutral_alpha_deg(PARAMS) + (6.5 if (k // 40) % 2 else -6.5)
            plant.step(0.1)
            depths.append(plant.depth_m)
        return np.array(depths)

    assert np.max(np.abs(trajectory(0.005) - trajectory(0.0025))) < 1e-3


def test_the_agent_cannot_rise_above_the_surface() -> None:
    plant = _plant(PARAMS.alpha_max_deg, depth_m=0.05)
    for _ in range(200):
        plant.step(0.1)
    assert plant.depth_m == 0.0 and plant.velocity_mps == 0.0


def test_the_actuator_moves_at_its_rated_speed() -> None:
    plant = _plant(0.0)
    plant.alpha_cmd_deg = PARAMS.alpha_max_deg
    plant.step(1.0)
    assert plant.alpha_deg == pytest.approx(PARAMS.alpha_rate_dps, rel=1e-9)
