"""The simulated hardware the on-board program sees: pressure sensor, stepper actuator, battery, clock.

The water (the plant) lives behind it; the program never reads the true depth or velocity, only
the pressure reading, its own stepper count and the battery voltage (see onboard.py).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from learning.spec import KernelSpec, direct_entry
from simulator.agent.mission import Battery
from simulator.parameters import PlantParams, kernel_params, neutral_alpha_deg
from simulator.plant.model import Plant
from simulator.plant.sensor import PressureSensor, depth_from_pressure_kernel


class SimulatedHardware:
    """Teensy peripherals over the simulated plant; `advance` lets agent time pass (simulated, not wall)."""

    def __init__(self, params: PlantParams, rng: np.random.Generator) -> None:
        self.params = params
        self._spec = kernel_params(params)
        self.plant = Plant(params, rng)
        self.sensor = PressureSensor(params, rng)
        self.battery = Battery()
        self._depth_from_pressure = direct_entry(depth_from_pressure_kernel, 0.0, self._spec)
        self.t_us = 0
        self.neutral_deg = params.alpha_max_deg / 2.0  # what the firmware assumes before it learns alpha_avg
        self.plant.set_state(depth_m=0.0, velocity_mps=0.0, alpha_deg=self.neutral_deg, alpha_cmd_deg=self.neutral_deg)

    # ---- what the firmware may use
    def read_pressure_pa(self) -> float:
        return self.sensor.sense(self.plant.state)

    def depth_from_pressure_m(self, pressure_pa: float) -> float:
        """The firmware's conversion z = (P - P0) / (rho g), with its calibration constants."""
        return float(self._depth_from_pressure(pressure_pa, self._spec))

    def set_actuator_cmd_deg(self, alpha_cmd_deg: float) -> None:
        self.plant.alpha_cmd_deg = min(max(alpha_cmd_deg, 0.0), self.params.alpha_max_deg)

    @property
    def actuator_cmd_deg(self) -> float:
        return float(self.plant.alpha_cmd_deg)

    @property
    def actuator_deg(self) -> float:
        """The stepper's angle as the firmware counts its own (open-loop) steps: the motor side of the gear train.

        The output angle (plant.alpha_deg, after backlash) stays inside the plant: the Teensy sketch reports
        NEUTRAL_DEG + steps * DEG_PER_STEP and cannot see it either.
        """
        return self.plant.motor_deg

    @property
    def battery_v(self) -> float:
        return self.battery.voltage_v

    @property
    def kernel_state(self) -> tuple[NDArray[np.float64], NDArray[np.uint64], KernelSpec]:
        """(plant state, sensor random stream, spec) for the compiled sensing of onboard_kernel.

        Those kernels read the plant only through the sensor kernel (and the true velocity where
        true_velocity_mps is allowed), as the firmware would.
        """
        return self.plant.state, self.sensor.rng_state, self._spec

    # ---- the world
    def advance(self, dt_s: float) -> None:
        """Let dt_s of agent time pass: the plant moves, the battery drains, the clock ticks."""
        self.plant.step(dt_s)
        self.battery.drain(dt_s)
        self.t_us += int(round(dt_s * 1e6))

    @property
    def true_depth_m(self) -> float:
        """For the radio model (blackout) and the paper preset's true-velocity learner only."""
        return self.plant.depth_m

    @property
    def true_velocity_mps(self) -> float:
        return self.plant.velocity_mps

    def place(self, depth_m: float) -> float:
        """The paper's simulated restart: put the agent at rest at depth_m, gear at true neutral."""
        neutral = neutral_alpha_deg(self.params)
        self.plant.set_state(depth_m=depth_m, velocity_mps=0.0, alpha_deg=neutral, alpha_cmd_deg=neutral)
        return neutral
