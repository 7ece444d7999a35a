"""The on-board program's compiled control step and packed SAMPLEs give what the Python classes and messages give."""

from __future__ import annotations

import numpy as np
import pytest

from learning import LearnerConfig
from learning.spec import direct_entry
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.kernel import recovery_period_kernel
from simulator.agent.mission import MissionConfig
from simulator.agent.program import OnboardProgram
from simulator.parameters import preset
from simulator.plant.model import Plant
from simulator.plant.observer import SlidingModeObserver
from simulator.plant.recovery import RecoveryController
from simulator.plant.sensor import PressureSensor, depth_from_pressure
from tests.simulator.checking_downlink import CheckingDownlink


def _run(preset_name: str, seed: int, steps: int) -> CheckingDownlink:
    params = preset(preset_name)
    rng = np.random.default_rng(seed)
    down = CheckingDownlink()
    program = OnboardProgram(params, LearnerConfig(), MissionConfig(), SimulatedHardware(params, rng), rng, down)
    down.program = program
    program.start(0)
    for _ in range(steps):
        program.step()
    assert program.learner.episode > 0  # both recovery and learning steps were checked
    return down


@pytest.mark.parametrize("preset_name", ["hardware", "paper"])
def test_every_sample_has_the_bytes_of_the_message_built_from_the_program_state(preset_name: str) -> None:
    down = _run(preset_name, seed=3, steps=6000)
    assert down.samples > 5000


def test_the_same_seed_gives_the_same_frames() -> None:
    assert _run("hardware", 5, 4000).payloads == _run("hardware", 5, 4000).payloads


def test_the_compiled_recovery_period_matches_sensor_observer_and_controller_called_one_by_one() -> None:
    params = preset("hardware")
    plant_a, plant_b = Plant(params), Plant(params)
    sensor_a, sensor_b = (PressureSensor(params, np.random.default_rng(1)) for _ in range(2))
    observer_a, observer_b = SlidingModeObserver(params), SlidingModeObserver(params)
    recovery_a, recovery_b = RecoveryController(params), RecoveryController(params)
    arrays = (plant_b.state, observer_b.state, recovery_b.state, sensor_b.rng_state)
    period = direct_entry(recovery_period_kernel, *arrays, True, 0.0, 0.0, plant_b.spec)
    dt = params.recovery_period_s
    for k in range(4000):
        hold_m = 0.3 if k < 2000 else 0.6
        pressure = sensor_a.read(plant_a.depth_m)
        depth = depth_from_pressure(pressure, params)
        velocity = observer_a.update(depth, dt)
        cmd = recovery_a.update(depth, velocity, hold_m, dt, plant_a.alpha_deg)
        expected = (pressure, depth, velocity, cmd, recovery_a.settled, recovery_a.gave_up)
        got = period(*arrays, True, hold_m, dt, plant_b.spec)
        assert got == expected
        for plant in (plant_a, plant_b):
            plant.alpha_cmd_deg = cmd
            plant.step(dt)
    assert recovery_b.settled  # the run reached the hand-over, so the flags were compared both ways
