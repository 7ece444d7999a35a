"""The pressure sensor, the velocity observer and the recovery controller, as a user would check them."""

from __future__ import annotations

import numpy as np
import pytest

from simulator.parameters import neutral_alpha_deg, preset
from simulator.plant.model import Plant
from simulator.plant.observer import SlidingModeObserver
from simulator.plant.recovery import RecoveryController
from simulator.plant.sensor import PressureSensor, depth_from_pressure

HARDWARE = preset("hardware")


def test_pressure_reading_has_the_datasheet_noise_and_resolution() -> None:
    sensor = PressureSensor(HARDWARE, np.random.default_rng(0))
    readings = np.array([sensor.read(1.0) for _ in range(5000)])
    assert np.all(readings == np.round(readings))  # 0.01 mbar = 1 Pa steps
    depths = np.array([depth_from_pressure(p, HARDWARE) for p in readings])
    assert depths.mean() == pytest.approx(1.0, abs=1e-4)
    assert depths.std() == pytest.approx(0.00066, rel=0.1)  # 0.065 mbar RMS = 0.66 mm of water


def test_pressure_sensor_saturates_beyond_its_range() -> None:
    sensor = PressureSensor(HARDWARE, np.random.default_rng(0))
    assert sensor.read(5.0) == HARDWARE.pressure_max_pa


@pytest.mark.parametrize("dt_s", [0.025, 0.1])
def test_observer_tracks_a_steady_descent_with_the_firmware_gain(dt_s: float) -> None:
    observer = SlidingModeObserver(HARDWARE)
    observer.reset(1.0)
    velocity = 0.0
    for k in range(1, int(5.0 / dt_s) + 1):
        velocity = observer.update(1.0 + 0.03 * k * dt_s, dt_s)
    # The firmware corrects x1 before it feeds x2, so a ramp reads (1 - rho dt / phi) of its slope:
    # 0.875 at the recovery period 0.025 s, only half at the learner's 0.1 s.
    gain = 1.0 - HARDWARE.observer_rho_mps * dt_s / HARDWARE.observer_phi_m
    assert velocity == pytest.approx(0.03 * gain, rel=0.02)


def test_recovery_settles_at_the_target_and_learns_the_neutral_angle() -> None:
    plant = Plant(HARDWARE, np.random.default_rng(0))  # hardware preset has a +0.5 % trim error
    plant.set_state(depth_m=0.0, alpha_deg=65.0, alpha_cmd_deg=65.0)
    controller = RecoveryController(HARDWARE)
    observer = SlidingModeObserver(HARDWARE)
    observer.reset(0.0)
    dt = HARDWARE.recovery_period_s
    while not (controller.settled or controller.gave_up):
        velocity = observer.update(plant.depth_m, dt)
        plant.alpha_cmd_deg = controller.update(plant.depth_m, velocity, 0.45, dt, alpha_deg=plant.alpha_deg)
        plant.step(dt)
    assert controller.settled
    assert abs(plant.depth_m - 0.45) < 0.01
    assert controller.alpha_avg_deg == pytest.approx(neutral_alpha_deg(HARDWARE), abs=1.0)
