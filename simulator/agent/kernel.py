"""The on-board program's sensing and recovery period as one compiled call each, chaining the existing kernels.

At --speed max the recovery controller runs 40 times per agent second; calling the sensor, the
depth conversion, the observer and the controller one by one from Python costs more than they
compute. These kernels chain them in the order the firmware runs them (onboard.py) and return the
numbers the SAMPLE of the step needs. The program calls them through `direct_entry`.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.spec import KernelSpec
from simulator.plant.kernel import MOTOR, ZDOT
from simulator.plant.observer import observer_update_kernel
from simulator.plant.recovery import recovery_gave_up, recovery_settled, recovery_update_kernel
from simulator.plant.sensor import depth_from_pressure_kernel, sense_pressure_kernel


@njit(cache=True, error_model="numpy")
def sense_kernel(
    plant: NDArray[np.float64],
    observer: NDArray[np.float64],
    rng_state: NDArray[np.uint64],
    use_observer: bool,
    dt_s: float,
    spec: KernelSpec,
) -> tuple[float, float, float]:
    """Read the pressure sensor, convert to depth, update the observer: (pressure_pa, depth_m, velocity_mps).

    Without the observer (the paper preset) the velocity is the plant's true one.
    """
    pressure_pa = sense_pressure_kernel(plant, spec, rng_state)
    depth_m = depth_from_pressure_kernel(pressure_pa, spec)
    estimate_mps = observer_update_kernel(observer, depth_m, dt_s, spec)
    return pressure_pa, depth_m, estimate_mps if use_observer else plant[ZDOT]


@njit(cache=True, error_model="numpy")
def recovery_period_kernel(
    plant: NDArray[np.float64],
    observer: NDArray[np.float64],
    recovery: NDArray[np.float64],
    rng_state: NDArray[np.uint64],
    use_observer: bool,
    hold_depth_m: float,
    dt_s: float,
    spec: KernelSpec,
) -> tuple[float, float, float, float, bool, bool]:
    """Sense, then one recovery controller period toward hold_depth_m.

    Returns (pressure_pa, depth_m, velocity_mps, alpha_cmd_deg, settled, gave_up).
    """
    pressure_pa, depth_m, velocity_mps = sense_kernel(plant, observer, rng_state, use_observer, dt_s, spec)
    # The motor side: the firmware counts its steps, the output angle behind the backlash is unknown to it.
    cmd_deg = recovery_update_kernel(recovery, depth_m, velocity_mps, plant[MOTOR], hold_depth_m, dt_s, spec)
    return (
        pressure_pa, depth_m, velocity_mps, cmd_deg,
        recovery_settled(recovery, spec), recovery_gave_up(recovery, spec),
    )
