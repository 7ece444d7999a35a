"""The simulated plant as a Python object over the compiled step the study runner also uses."""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from learning.spec import KernelSpec, direct_entry
from simulator.parameters import PlantParams, kernel_params, neutral_alpha_deg
from simulator.plant.kernel import ALPHA, MOTOR, PLANT_SIZE, SENSED_Z, ZDOT, Z, plant_step


class Plant:
    """Depth, velocity and gear angle of the agent; step(dt_s) integrates holding alpha_cmd_deg."""

    def __init__(self, params: PlantParams, rng: np.random.Generator | None = None) -> None:
        self._params = params
        self._spec = kernel_params(params)
        # The plant itself is deterministic; rng is accepted for a uniform constructor signature.
        self._rng = rng
        self._state = np.zeros(PLANT_SIZE)
        self.alpha_cmd_deg = neutral_alpha_deg(params)
        self._state[ALPHA] = self.alpha_cmd_deg
        self._state[MOTOR] = self.alpha_cmd_deg
        self._step = direct_entry(plant_step, self._state, 0.0, 0.0, self._spec)

    @property
    def params(self) -> PlantParams:
        return self._params

    @property
    def spec(self) -> KernelSpec:
        """The parameters as the kernels take them."""
        return self._spec

    @property
    def state(self) -> NDArray[np.float64]:
        """The live state array (plant_kernel layout), for compiled steps that chain the kernels."""
        return self._state

    @property
    def depth_m(self) -> float:
        return float(self._state[Z])

    @property
    def velocity_mps(self) -> float:
        return float(self._state[ZDOT])

    @property
    def alpha_deg(self) -> float:
        """The gear train's output angle (what moves the piston); no agent can read it."""
        return float(self._state[ALPHA])

    @property
    def motor_deg(self) -> float:
        """The stepper side of the gear train: the angle an agent counts from its own steps."""
        return float(self._state[MOTOR])

    def set_state(
        self,
        depth_m: float | None = None,
        velocity_mps: float | None = None,
        alpha_deg: float | None = None,
        alpha_cmd_deg: float | None = None,
    ) -> None:
        """Place the agent; fields left None keep their value (a placed gear and port start settled)."""
        if depth_m is not None:
            self._state[Z] = depth_m
            self._state[SENSED_Z] = depth_m
        if velocity_mps is not None:
            self._state[ZDOT] = velocity_mps
        if alpha_deg is not None:
            self._state[ALPHA] = alpha_deg
            self._state[MOTOR] = alpha_deg
        if alpha_cmd_deg is not None:
            self.alpha_cmd_deg = alpha_cmd_deg

    def step(self, dt_s: float) -> None:
        """Integrate dt_s seconds with fixed sub-steps, holding the current command."""
        self._step(self._state, self.alpha_cmd_deg, dt_s, self._spec)
