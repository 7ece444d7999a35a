"""The MS5803-01BA pressure sensor: noise, 0.01 mbar quantisation, range; and depth from pressure.

A real sensor adds a bias that drifts, a lagging port (integrated by the plant, simulator/plant/kernel.py),
coloured noise and a depth-scale error: sense_pressure_kernel reads them from the plant state; each is 0 by
default, and then it draws and returns exactly what read_pressure_kernel does.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.rng import new_stream, normal, normal_ziggurat
from learning.spec import KernelSpec, direct_entry
from simulator.parameters import PlantParams, kernel_params
from simulator.plant.kernel import CLOCK_S, LAST_READ_S, NOISE_PA, PLANT_SIZE, SENSED_Z, Z


@njit(cache=True, error_model="numpy", inline="always")
def _noise_draw(spec: KernelSpec, rng_state: NDArray[np.uint64]) -> float:
    """A standard normal for the sensor's noise, by the preset's draw (PlantParams.ziggurat_noise)."""
    return normal_ziggurat(rng_state) if spec.ziggurat_noise else normal(rng_state)


@njit(cache=True, error_model="numpy", inline="always")
def read_pressure_kernel(depth_m: float, spec: KernelSpec, rng_state: NDArray[np.uint64]) -> float:
    """Absolute pressure in Pa as the sensor reports it at depth_m."""
    pressure_pa = spec.surface_pressure_pa + spec.water_density_kgpm3 * spec.gravity_mps2 * depth_m
    pressure_pa += spec.pressure_noise_pa * _noise_draw(spec, rng_state)
    pressure_pa = np.round(pressure_pa / spec.pressure_lsb_pa) * spec.pressure_lsb_pa
    return min(max(pressure_pa, spec.pressure_min_pa), spec.pressure_max_pa)


@njit(cache=True, error_model="numpy", inline="always")
def sense_pressure_kernel(plant: NDArray[np.float64], spec: KernelSpec, rng_state: NDArray[np.uint64]) -> float:
    """Absolute pressure in Pa as the real sensor reports it for the plant state (kernel.py layout)."""
    depth_m = plant[SENSED_Z] if spec.pressure_lag_s > 0.0 else plant[Z]
    if spec.depth_scale_error != 0.0:
        depth_m *= 1.0 + spec.depth_scale_error
    pressure_pa = spec.surface_pressure_pa + spec.water_density_kgpm3 * spec.gravity_mps2 * depth_m
    if spec.pressure_bias_pa != 0.0 or spec.pressure_drift_pa_per_s != 0.0:
        pressure_pa += spec.pressure_bias_pa + spec.pressure_drift_pa_per_s * plant[CLOCK_S]
    if spec.pressure_noise_corr_s > 0.0:
        # AR(1) over the time since the last reading: the same stationary spread at any reading rate.
        keep = np.exp(-(plant[CLOCK_S] - plant[LAST_READ_S]) / spec.pressure_noise_corr_s)
        plant[NOISE_PA] = keep * plant[NOISE_PA] + np.sqrt(1.0 - keep * keep) * spec.pressure_noise_pa * _noise_draw(
            spec, rng_state)
        plant[LAST_READ_S] = plant[CLOCK_S]
        pressure_pa += plant[NOISE_PA]
    else:
        pressure_pa += spec.pressure_noise_pa * _noise_draw(spec, rng_state)
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
        self._sense = direct_entry(sense_pressure_kernel, np.zeros(PLANT_SIZE), self._spec, self._rng_state)

    @property
    def rng_state(self) -> NDArray[np.uint64]:
        """The sensor's own random stream, for compiled steps that chain the kernels."""
        return self._rng_state

    def read(self, depth_m: float) -> float:
        """Pressure in Pa at depth_m."""
        return float(self._read(depth_m, self._spec, self._rng_state))

    def sense(self, plant_state: NDArray[np.float64]) -> float:
        """Pressure in Pa for a plant state (kernel.py layout) with the real sensor's bias, lag and noise."""
        return float(self._sense(plant_state, self._spec, self._rng_state))


def depth_from_pressure(pressure_pa: float, params: PlantParams) -> float:
    """Depth in m from an absolute pressure in Pa."""
    return float(depth_from_pressure_kernel(float(pressure_pa), kernel_params(params)))
