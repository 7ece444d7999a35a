"""Each real-robot imperfection of the plant is measurable, settable from a --params file, and off by default."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from simulator.errors import ParamsError
from simulator.parameters import PlantParams, load_params, preset
from simulator.plant.kernel import jittered_period_s
from simulator.plant.model import Plant
from simulator.plant.sensor import PressureSensor, depth_from_pressure

RHO_G = 1000.0 * 9.81


def _readings(params: PlantParams, depth_m: float, n: int, dt_s: float = 0.1) -> np.ndarray:
    """n readings of a sensor over a plant held at depth_m (the gear at neutral, no motion)."""
    plant = Plant(params)
    sensor = PressureSensor(params, np.random.default_rng(3))
    out = []
    for _ in range(n):
        plant.set_state(depth_m=depth_m, velocity_mps=0.0)
        plant.step(dt_s)
        plant.set_state(depth_m=depth_m, velocity_mps=0.0)
        out.append(sensor.sense(plant.state))
    return np.array(out)


def test_ideal_sensor_sense_is_the_plain_read() -> None:
    params = preset("hardware")
    plant = Plant(params)
    a = PressureSensor(params, np.random.default_rng(5))
    b = PressureSensor(params, np.random.default_rng(5))
    for depth in np.linspace(0.0, 1.0, 50):
        plant.set_state(depth_m=float(depth))
        assert a.sense(plant.state) == b.read(float(depth))


def test_bias_shifts_the_mean_reading() -> None:
    base = _readings(preset("hardware"), 0.4, 400)
    biased = _readings(replace(preset("hardware"), pressure_bias_pa=50.0), 0.4, 400)
    assert biased.mean() - base.mean() == pytest.approx(50.0, abs=1.0)  # same draws: only the offset differs


def test_drift_grows_with_plant_time() -> None:
    readings = _readings(replace(preset("hardware"), pressure_drift_pa_per_s=1.0, pressure_noise_pa=0.0), 0.4, 100)
    # 0.1 s per reading at 1 Pa/s, quantised to 1 Pa: 10 s later the reading is 10 Pa higher.
    assert readings[-1] - readings[0] == pytest.approx(9.9, abs=1.0)


def test_depth_scale_error_scales_the_sensed_depth() -> None:
    params = replace(preset("hardware"), depth_scale_error=0.03, pressure_noise_pa=0.0, pressure_lsb_pa=0.01)
    depth = depth_from_pressure(_readings(params, 2.0, 1)[0], params)
    assert depth == pytest.approx(2.06, abs=1e-5)


def test_lag_delays_a_step() -> None:
    params = replace(preset("hardware"), pressure_lag_s=0.3, pressure_noise_pa=0.0, pressure_lsb_pa=0.01)
    plant = Plant(params)
    sensor = PressureSensor(params, np.random.default_rng(1))
    plant.set_state(depth_m=0.0, velocity_mps=0.0)
    plant.state[0] = 1.0  # the hull jumps 1 m; the port has not seen it yet
    sensed = []
    for _ in range(10):
        plant.state[0], plant.state[1] = 1.0, 0.0
        plant.step(0.1)
        sensed.append(depth_from_pressure(sensor.sense(plant.state), params))
    # First order: 1 - exp(-t / 0.3) of the step after t seconds.
    assert sensed[2] == pytest.approx(1.0 - np.exp(-1.0), abs=2e-3)
    assert sensed[-1] == pytest.approx(1.0 - np.exp(-1.0 / 0.3), abs=2e-3)


def test_coloured_noise_keeps_its_spread_and_gains_correlation() -> None:
    white = _readings(replace(preset("hardware"), pressure_lsb_pa=0.01), 0.4, 4000)
    coloured = _readings(replace(preset("hardware"), pressure_lsb_pa=0.01, pressure_noise_corr_s=1.0), 0.4, 4000)

    def lag1(x: np.ndarray) -> float:
        x = x - x.mean()
        return float(np.dot(x[1:], x[:-1]) / np.dot(x, x))

    assert abs(lag1(white)) < 0.05
    assert lag1(coloured) == pytest.approx(np.exp(-0.1), abs=0.05)
    assert coloured.std() == pytest.approx(6.5, rel=0.25)


def _gear_run(params: PlantParams, commands: list[float]) -> list[float]:
    plant = Plant(params)
    plant.set_state(depth_m=0.4, velocity_mps=0.0, alpha_deg=65.0, alpha_cmd_deg=65.0)
    out = []
    for cmd in commands:
        plant.alpha_cmd_deg = cmd
        plant.step(1.0)
        out.append(plant.alpha_deg)
    return out


def test_backlash_makes_a_dead_zone_on_reversal() -> None:
    params = replace(preset("hardware"), backlash_deg=3.0)
    up, back, down = _gear_run(params, [70.0, 68.0, 60.0])
    assert up == pytest.approx(68.5)  # the motor reached 70, the output trails it by half the lost motion
    assert back == pytest.approx(68.5)  # a 2 deg reversal is swallowed by the 3 deg of lost motion
    assert down == pytest.approx(61.5)
    assert _gear_run(preset("hardware"), [70.0, 68.0]) == [70.0, 68.0]


def test_dead_band_ignores_small_commands() -> None:
    params = replace(preset("hardware"), dead_band_deg=1.0)
    small, large = _gear_run(params, [65.4, 68.0])
    assert small == 65.0  # within half the band: the stepper does not start
    assert large == pytest.approx(67.5, abs=0.2)  # it stops within half the band short of the command


def test_jitter_spreads_the_control_period() -> None:
    spec = Plant(replace(preset("hardware"), control_jitter_s=0.01)).spec
    stream = np.array([np.uint64(42)])
    periods = np.array([jittered_period_s(0.1, spec, stream) for _ in range(2000)])
    assert periods.min() >= 0.09 and periods.max() <= 0.11
    assert periods.std() == pytest.approx(0.02 / np.sqrt(12), rel=0.1)
    ideal = Plant(preset("hardware")).spec
    before = stream.copy()
    assert jittered_period_s(0.1, ideal, stream) == 0.1 and stream[0] == before[0]  # no draw when off


def test_imperfections_load_from_a_params_file(tmp_path: Path) -> None:
    path = tmp_path / "robot.toml"
    path.write_text("backlash_deg = 1.5\npressure_bias_pa = -20\npressure_noise_corr_s = 0.3\n")
    params = load_params(path, preset("hardware"))
    assert (params.backlash_deg, params.pressure_bias_pa, params.pressure_noise_corr_s) == (1.5, -20, 0.3)
    path.write_text("dead_band_deg = -1\n")
    with pytest.raises(ParamsError, match="dead_band_deg"):
        load_params(path, preset("hardware"))
    path.write_text("control_jitter_s = 0.2\n")
    with pytest.raises(ParamsError, match="control_jitter_s"):
        load_params(path, preset("hardware"))
