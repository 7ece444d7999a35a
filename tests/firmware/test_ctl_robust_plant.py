"""The C plant and sensor with every real-robot imperfection on against the Python kernels, step for step.

Backlash, dead band, port lag and clock (plant), bias, drift, depth-scale error and AR(1) noise (sensor),
and the jittered control period: the C port the QEMU board runs must agree with simulator/plant/.
"""

from __future__ import annotations

import ctypes
from dataclasses import replace

import numpy as np
import pytest

from learning.rng import new_stream
from simulator.parameters import PlantParams, preset
from simulator.plant.kernel import CLOCK_S, LAST_READ_S, MOTOR, NOISE_PA, SENSED_Z, jittered_period_s
from simulator.plant.model import Plant
from simulator.plant.sensor import PressureSensor
from tests.firmware.ctl_lib import PlantParamsC, PlantStateC, RngC, SensorParamsC, build_ctl_library

SEED = 11
ROUGH = dict(
    backlash_deg=2.0, dead_band_deg=0.8, pressure_lag_s=0.2, control_jitter_s=0.01, pressure_bias_pa=40.0,
    pressure_drift_pa_per_s=0.02, pressure_noise_corr_s=0.5, depth_scale_error=0.02,
)
_SENSOR_NAMES = {
    "bias_pa": "pressure_bias_pa", "drift_pa_per_s": "pressure_drift_pa_per_s",
    "noise_corr_s": "pressure_noise_corr_s", "depth_scale_error": "depth_scale_error", "lag_s": "pressure_lag_s",
    "noise_pa": "pressure_noise_pa", "lsb_pa": "pressure_lsb_pa", "min_pa": "pressure_min_pa",
    "max_pa": "pressure_max_pa",
}


@pytest.fixture(scope="module")
def ctl(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    return build_ctl_library(tmp_path_factory.mktemp("ctl"))


def _c_params(params: PlantParams) -> tuple[PlantParamsC, SensorParamsC]:
    plant = PlantParamsC(*(getattr(params, f[0]) for f in PlantParamsC._fields_))
    sensor = SensorParamsC(*(getattr(params, _SENSOR_NAMES.get(f[0], f[0])) for f in SensorParamsC._fields_))
    return plant, sensor


def test_c_defaults_are_the_ideal_plant(ctl: ctypes.CDLL) -> None:
    params = preset("hardware")
    c, s = PlantParamsC(), SensorParamsC()
    ctl.plant_hardware_params(ctypes.byref(c))
    ctl.sensor_hardware_params(ctypes.byref(s))
    assert (c.backlash_deg, c.dead_band_deg, c.pressure_lag_s, c.control_jitter_s) == (
        params.backlash_deg, params.dead_band_deg, params.pressure_lag_s, params.control_jitter_s) == (0, 0, 0, 0)
    assert (s.bias_pa, s.drift_pa_per_s, s.noise_corr_s, s.depth_scale_error, s.lag_s) == (0, 0, 0, 0, 0)


def test_c_rough_plant_and_sensor_follow_python(ctl: ctypes.CDLL) -> None:
    params = replace(preset("hardware"), **ROUGH)
    c_plant, c_sensor = _c_params(params)
    plant = Plant(params)
    sensor = PressureSensor(params, np.random.default_rng(SEED))
    c_rng = RngC(int(new_stream(np.random.default_rng(SEED))[0]))
    jitter_py = new_stream(np.random.default_rng(SEED + 2))
    c_jitter = RngC(int(jitter_py[0]))
    plant.set_state(depth_m=0.4, velocity_mps=0.0, alpha_deg=62.0)
    x = PlantStateC()
    ctl.plant_place(ctypes.byref(x), 0.4, 0.0, 62.0)
    cmd_rng = np.random.default_rng(SEED + 1)
    gaps = []
    for step in range(3000):
        cmd = float(cmd_rng.uniform(50.0, 80.0))
        nominal = (0.1, 0.025)[step % 2]
        dt = jittered_period_s(nominal, plant.spec, jitter_py)
        assert ctl.plant_jittered_period_s(ctypes.byref(c_plant), ctypes.byref(c_jitter), nominal) == dt
        plant.alpha_cmd_deg = cmd
        plant.step(dt)
        ctl.plant_step(ctypes.byref(x), ctypes.byref(c_plant), cmd, dt)
        s = plant.state
        for c_value, py_value in ((x.z_m, s[0]), (x.zdot_mps, s[1]), (x.alpha_deg, s[2]), (x.motor_deg, s[MOTOR]),
                                  (x.sensed_z_m, s[SENSED_Z]), (x.clock_s, s[CLOCK_S])):
            assert c_value == pytest.approx(py_value, abs=1e-9)
        assert ctl.sensor_sense_pa(ctypes.byref(c_sensor), ctypes.byref(c_rng), ctypes.byref(x)) == sensor.sense(s)
        assert x.noise_pa == pytest.approx(s[NOISE_PA], abs=1e-9) and x.last_read_s == s[LAST_READ_S]
        gaps.append(abs(s[MOTOR] - s[2]))
    # The run exercised the imperfections: the gear train opened up to its lost motion.
    assert max(gaps) == pytest.approx(ROUGH["backlash_deg"] / 2, abs=1e-9)
