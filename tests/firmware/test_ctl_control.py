"""The C observer, recovery controller, plant and sensor against the Python reference on the same inputs.

The depth sequence is recorded from the Python closed loop (plant, noisy sensor, observer, recovery
controller, `hardware` preset, with and without gear backlash); the C observer and controller get the same
measured depths and gear angles and must give the same velocity estimates and commands within float32
rounding, and settle on the same step. The C plant (double, as the Python) follows the Python plant to 1e-9 on the same
commands; the C sensor, seeded with the Python sensor's stream, reads the same pressures.
"""

from __future__ import annotations

import ctypes

import numpy as np
import pytest

from learning.rng import new_stream
from simulator.parameters import neutral_alpha_deg, preset, with_overrides
from simulator.plant.model import Plant
from simulator.plant.observer import SlidingModeObserver
from simulator.plant.recovery import RecoveryController
from simulator.plant.sensor import PressureSensor, depth_from_pressure
from tests.firmware.ctl_lib import (
    PlantParamsC,
    PlantStateC,
    RecoveryParams,
    RecoveryState,
    RngC,
    SensorParamsC,
    SmoGains,
    SmoState,
    build_ctl_library,
)

SEED = 7
F32_RTOL = 1e-4  # float32 against float64 after thousands of steps of a contracting filter


@pytest.fixture(scope="module")
def ctl(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    return build_ctl_library(tmp_path_factory.mktemp("ctl"))


def test_c_plant_params_are_the_hardware_preset(ctl: ctypes.CDLL) -> None:
    params = preset("hardware")
    c = PlantParamsC()
    ctl.plant_hardware_params(ctypes.byref(c))
    for name in (f[0] for f in PlantParamsC._fields_):
        assert getattr(c, name) == getattr(params, name), name
    assert ctl.plant_neutral_alpha_deg(ctypes.byref(c)) == pytest.approx(neutral_alpha_deg(params), abs=1e-12)
    s = SensorParamsC()
    ctl.sensor_hardware_params(ctypes.byref(s))
    assert (s.surface_pressure_pa, s.noise_pa, s.lsb_pa, s.min_pa, s.max_pa) == (
        params.surface_pressure_pa, params.pressure_noise_pa, params.pressure_lsb_pa,
        params.pressure_min_pa, params.pressure_max_pa)


def test_c_plant_follows_python_plant(ctl: ctypes.CDLL) -> None:
    params = preset("hardware")
    plant = Plant(params)
    c_params = PlantParamsC()
    ctl.plant_hardware_params(ctypes.byref(c_params))
    start = dict(depth_m=0.3, velocity_mps=0.0, alpha_deg=60.0)
    plant.set_state(**start)
    x = PlantStateC()
    ctl.plant_place(ctypes.byref(x), 0.3, 0.0, 60.0)
    rng = np.random.default_rng(SEED)
    depths = []
    for step in range(3000):
        # commands beyond both ends of the range: it sinks for a while, then rises to the surface
        cmd = float(rng.uniform(-10.0, 100.0) if step < 1500 else rng.uniform(40.0, 140.0))
        dt = (0.1, 0.025, 0.0123)[step % 3]
        plant.alpha_cmd_deg = cmd
        plant.step(dt)
        ctl.plant_step(ctypes.byref(x), ctypes.byref(c_params), cmd, dt)
        assert x.z_m == pytest.approx(plant.depth_m, abs=1e-9)
        assert x.zdot_mps == pytest.approx(plant.velocity_mps, abs=1e-9)
        assert x.alpha_deg == pytest.approx(plant.alpha_deg, abs=1e-9)
        depths.append(plant.depth_m)
    assert max(depths) > 1.0 and min(depths[1500:]) == 0.0  # dived, then met the free surface


def test_c_sensor_reads_python_pressures(ctl: ctypes.CDLL) -> None:
    params = preset("hardware")
    seed_rng = np.random.default_rng(SEED)
    stream = int(new_stream(np.random.default_rng(SEED))[0])
    sensor = PressureSensor(params, seed_rng)
    c_params = SensorParamsC()
    ctl.sensor_hardware_params(ctypes.byref(c_params))
    c_rng = RngC(stream)
    depths = np.random.default_rng(SEED + 1).uniform(-0.5, 3.5, 5000)  # beyond both ends of the range
    for depth in depths:
        assert ctl.sensor_read_pa(ctypes.byref(c_params), ctypes.byref(c_rng), float(depth)) == sensor.read(depth)


@pytest.mark.parametrize("gear", [{}, {"backlash_deg": 2.0, "dead_band_deg": 0.5}], ids=["ideal-gear", "backlash"])
def test_c_observer_and_recovery_follow_python(ctl: ctypes.CDLL, gear: dict[str, float]) -> None:
    # With backlash the controller's inner layer (recovery_near_gain_deg) is what lets it settle at all.
    params = with_overrides(preset("hardware"), gear)
    rng = np.random.default_rng(SEED)
    plant = Plant(params)
    sensor = PressureSensor(params, rng)
    observer = SlidingModeObserver(params)
    recovery = RecoveryController(params)
    gains = SmoGains(params.observer_rho_mps, params.observer_tau_s, params.observer_phi_m)
    rp = RecoveryParams(
        params.recovery_lambda_per_s, params.recovery_phi_mps, params.recovery_gain_deg,
        params.recovery_avg_time_s, params.settle_depth_m, params.settle_velocity_mps,
        params.settle_time_s, params.give_up_s, params.alpha_max_deg, params.recovery_near_gain_deg,
        params.recovery_near_phi_mps)
    smo, rec = SmoState(), RecoveryState()
    ctl.smo_reset(ctypes.byref(smo), 0.0)
    ctl.recovery_init(ctypes.byref(rec), params.alpha_max_deg / 2.0)
    plant.set_state(depth_m=0.0, velocity_mps=0.0, alpha_deg=65.0, alpha_cmd_deg=65.0)
    observer.reset(0.0)
    dt = params.recovery_period_s
    settled = ctypes.c_bool()
    gave_up = ctypes.c_bool()
    py_settled_at = c_settled_at = -1
    setpoint = 0.45
    for step in range(int(60.0 / dt)):
        depth = float(np.float32(depth_from_pressure(sensor.read(plant.depth_m), params)))
        alpha = float(np.float32(plant.alpha_deg))
        v_py = observer.update(depth, dt)
        v_c = ctl.smo_update(ctypes.byref(smo), ctypes.byref(gains), depth, dt)
        assert v_c == pytest.approx(v_py, rel=F32_RTOL, abs=1e-6)
        # the controller gets the Python estimate, so each module is checked on its own inputs
        v_in = float(np.float32(v_py))
        cmd_py = recovery.update(depth, v_in, setpoint, dt, alpha_deg=alpha)
        cmd_c = ctl.recovery_step(ctypes.byref(rec), ctypes.byref(rp), depth, v_in, setpoint, alpha, dt,
                                  ctypes.byref(settled), ctypes.byref(gave_up))
        assert cmd_c == pytest.approx(cmd_py, rel=F32_RTOL, abs=1e-4)
        assert ctl.recovery_alpha_avg_deg(ctypes.byref(rec)) == pytest.approx(recovery.alpha_avg_deg, rel=F32_RTOL)
        assert gave_up.value == recovery.gave_up
        if recovery.settled and py_settled_at < 0:
            py_settled_at = step
        if settled.value and c_settled_at < 0:
            c_settled_at = step
        plant.alpha_cmd_deg = cmd_py
        plant.step(dt)
    assert py_settled_at > 0, "the recorded recovery never settled: the test would check nothing"
    assert c_settled_at == py_settled_at
    ctl.recovery_restart(ctypes.byref(rec))
    recovery.restart()
    assert rec.calm_s == 0.0 and rec.elapsed_s == 0.0
    assert rec.avg_deg == pytest.approx(recovery.alpha_avg_deg, rel=F32_RTOL)
