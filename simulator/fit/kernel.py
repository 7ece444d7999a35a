"""The compiled plant run over every window at once: depth and gear angle at each recorded sample time."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.spec import KernelSpec
from simulator.plant.kernel import ALPHA, PLANT_SIZE, Z, plant_place, plant_step


@njit(cache=True, error_model="numpy")
def simulate_windows(
    spec: KernelSpec, t_s: NDArray[np.float64], cmd_deg: NDArray[np.float64], alpha0_deg: NDArray[np.float64],
    starts: NDArray[np.int64], ends: NDArray[np.int64], z0_m: NDArray[np.float64], v0_mps: NDArray[np.float64],
    depth_out: NDArray[np.float64], alpha_out: NDArray[np.float64],
) -> None:
    """Each window from its own start state (z0, v0, alpha0) under the recorded commands, held between samples."""
    state = np.zeros(PLANT_SIZE)  # the fitted plant is the ideal one: its gear and port states start settled
    for w in range(len(starts)):
        first, stop = starts[w], ends[w]
        plant_place(state, z0_m[w], v0_mps[w], alpha0_deg[w])
        depth_out[first] = state[Z]
        alpha_out[first] = state[ALPHA]
        for i in range(first, stop - 1):
            plant_step(state, cmd_deg[i], t_s[i + 1] - t_s[i], spec)
            depth_out[i + 1] = state[Z]
            alpha_out[i + 1] = state[ALPHA]
