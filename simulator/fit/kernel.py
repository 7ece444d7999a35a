"""The compiled plant run over every window at once: sensed depth and counted gear angle at each sample time."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.spec import KernelSpec
from simulator.plant.kernel import ALPHA, MOTOR, PLANT_SIZE, SENSED_Z, ZDOT, Z, plant_step


@njit(cache=True, error_model="numpy")
def gear_outputs(history_deg: NDArray[np.float64], reset: NDArray[np.bool_], start_rows: NDArray[np.int64],
                 half_lash_deg: float, out: NDArray[np.float64]) -> None:
    """The gear's output angle at each window's start: the recorded motor angle run through the play of the
    backlash from the last restart (gear train closed there, as plant_place leaves it).

    Between two samples the motor moves one way only (toward the held command), and the play of a monotone
    path is the play of its end point: the samples alone give the output exactly.
    """
    alpha = history_deg[0] if len(history_deg) > 0 else 0.0
    j = 0
    for i in range(len(history_deg)):
        motor = history_deg[i]
        if reset[i]:
            alpha = motor
        else:
            alpha = min(max(alpha, motor - half_lash_deg), motor + half_lash_deg)
        while j < len(start_rows) and start_rows[j] == i:
            out[j] = alpha
            j += 1


@njit(cache=True, error_model="numpy")
def simulate_windows(
    spec: KernelSpec, t_s: NDArray[np.float64], cmd_deg: NDArray[np.float64], motor0_deg: NDArray[np.float64],
    alpha0_deg: NDArray[np.float64], starts: NDArray[np.int64], ends: NDArray[np.int64], z0_m: NDArray[np.float64],
    v0_mps: NDArray[np.float64], depth_out: NDArray[np.float64], motor_out: NDArray[np.float64],
) -> None:
    """Each window from its own start state under the recorded commands, held between samples.

    The plant is the simulator's, imperfections included: the stepper (rate, dead band) from the recorded motor
    angle, the output behind the backlash from alpha0_deg, the port's lag. depth_out is the depth the port
    senses (the recording's, before bias, scale and noise); z0_m is that sensed depth at the window's start, and
    the true depth starts ahead of it by what the lag holds back of a steady descent at v0.
    """
    state = np.zeros(PLANT_SIZE)
    lagged = spec.pressure_lag_s > 0.0
    for w in range(len(starts)):
        first, stop = starts[w], ends[w]
        state[Z] = z0_m[w] + (spec.pressure_lag_s * v0_mps[w] if lagged else 0.0)
        state[ZDOT] = v0_mps[w]
        state[SENSED_Z] = z0_m[w]
        state[MOTOR] = motor0_deg[w]
        state[ALPHA] = alpha0_deg[w]
        depth_out[first] = z0_m[w]
        motor_out[first] = motor0_deg[w]
        for i in range(first, stop - 1):
            plant_step(state, cmd_deg[i], t_s[i + 1] - t_s[i], spec)
            depth_out[i + 1] = state[SENSED_Z] if lagged else state[Z]
            motor_out[i + 1] = state[MOTOR]
