"""The MS5803-01BA pressure sensor: noise, 0.01 mbar quantisation, range; and depth from pressure."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.rng import new_stream, normal
from learning.spec import KernelSpec, direct_entry
from simulator.parameters import PlantParams, kernel_params


@njit(cache=True, error_model="numpy", inline="always")
def read_pressure_kernel(depth_m: float, spec: KernelSpec, rng_state: NDArray[np.uint64]) -> float:
    """Absolute pressure in Pa as the sensor reports it at depth_m."""
    pressure_pa = spec.surface_pressure_pa + spec.water_density_kgpm3 * spec.gravity_mps2 * depth_m
    pressure_pa += spec.pressure_noise_pa * normal(rng_state)
    pressure_pa = np.round(pressure_pa / spec.pressure_lsb_pa) * spec.pressure_lsb_pa
    return min(max(pressure_pa, spec.pressure_min_pa), spec.pressure_max_pa)


@njit(cache=True, error_model="numpy", inline="always")
def depth_from_pressure_kernel(pressure_pa: float, spec: KernelSpec) -> float:
    """z = (P - P0) / (rho g), as the firmware computes it."""
    return (pressure_pa - spec.surface_pressure_pa) / (spec.water_density_kgpm3 * spec.gravity_mps2)


class PressureSensor:
    """A noisy, quantised, range-limited pressure reading with its own random stream."""

    def __init__(self, params: PlantParams, rng: np.random.Generator) -> None:
        self._spec = kernel_params(params)
        self._rng_state = new_stream(rng)
        self._read = direct_entry(read_pressure_kernel, 0.0, self._spec, self._rng_state)

    @property
    def rng_state(self) -> NDArray[np.uint64]:
        """The sensor's own random stream, for compiled steps that chain the kernels."""
        return self._rng_state

    def read(self, depth_m: float) -> float:
        """Pressure in Pa at depth_m."""
        return float(self._read(depth_m, self._spec, self._rng_state))


def depth_from_pressure(pressure_pa: float, params: PlantParams) -> float:
    """Depth in m from an absolute pressure in Pa."""
    return float(depth_from_pressure_kernel(float(pressure_pa), kernel_params(params)))
