"""The whole fit: actuator rate from the gear's own record, the hull by least squares, the sensor's noise, and
which figures the data could identify (and what excitation would identify the others)."""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from simulator.fit.model import HULL_FIELDS, Z95, EvalHook, HullFit, fit_hull
from simulator.fit.reader import FitError, ReadHook, Samples, read_samples
from simulator.fit.windows import Windows, cut_windows
from simulator.parameters import PlantParams, neutral_alpha_deg

NEUTRAL = "neutral_angle_deg"  # reported beside trim_error_fraction, which it is a function of
MIN_RATE_MOVES = 5  # saturated gear moves needed to measure the actuator's rate


@dataclass(frozen=True)
class Estimate:
    """One fitted figure (a PlantParams field, or the neutral angle derived from the trim)."""

    name: str
    value: float
    half_width: float  # of the 95 % interval; nan when not identified
    identified: bool
    needs: str = ""  # when not identified: the excitation that would identify it


@dataclass
class FitResult:
    params: PlantParams  # the base with every identified figure replaced
    estimates: list[Estimate]
    residual_rms_m: float
    windows: Windows
    hull: HullFit
    files: list[Path]
    notes: list[str] = field(default_factory=list)
    wall_s: float = 0.0

    def estimate(self, name: str) -> Estimate:
        return next(e for e in self.estimates if e.name == name)


def _neutral_per_trim(params: PlantParams) -> float:
    """d(neutral angle)/d(trim fraction), deg: the neutral angle is linear in the trim."""
    return params.alpha_max_deg * params.mass_kg / params.water_density_kgpm3 / params.stroke_volume_m3


# The widest 95 % half-interval at which a figure counts as identified, and what identifies it otherwise.
def _limits(params: PlantParams) -> dict[str, float]:
    per_deg_m3 = params.stroke_volume_m3 / params.alpha_max_deg
    return {
        "added_mass_kg": 0.02,  # a fifth of the 0.10 kg estimate
        "drag_kgpm": 0.25,  # a quarter of the authors' 1 kg/m
        "trim_error_fraction": 0.5 / _neutral_per_trim(params),  # half a degree of neutral angle
        # Over a metre of depth, less than half a degree's worth of volume.
        "compressibility_m3pm": 0.5 * per_deg_m3,
    }


def _needs(name: str, windows: Windows) -> str:
    speed = np.abs(np.diff(windows.depth_m)) / np.maximum(np.diff(windows.t_s), 1e-9)
    span = float(np.ptp(windows.depth_m))
    step = float(np.ptp(windows.cmd_deg))
    reach_cmps = 100 * np.percentile(speed, 99)
    return {
        "added_mass_kg": f"needs steps of the actuator command (hover at two depths; the commands span {step:.1f} deg)",
        "drag_kgpm": f"needs speeds above 5 cm/s (the recordings reach about {reach_cmps:.1f} cm/s)",
        "trim_error_fraction": "needs time hovering at a steady depth (the recovery controller, `dive hover`)",
        "compressibility_m3pm": f"needs hovering at depths at least 0.5 m apart (the recordings span {span:.2f} m)",
    }[name]


def fit_rate(params: PlantParams, windows: Windows) -> Estimate:
    """The stepper's top rate, from sample intervals where the gear could not reach its command."""
    moves, dts = [], []
    owner = windows.owner()
    same = owner[1:] == owner[:-1]
    target = np.clip(windows.cmd_deg[:-1], 0.0, params.alpha_max_deg)
    gap = target - windows.alpha_deg[:-1]
    move = np.diff(windows.alpha_deg)
    dt = np.diff(windows.t_s)
    # Saturated: moved toward the command, by a visible amount, and stopped clearly short of it.
    saturated = same & (np.sign(move) == np.sign(gap)) & (np.abs(move) > 0.05) & (np.abs(move) < np.abs(gap) - 0.01)
    moves, dts = np.abs(move[saturated]), dt[saturated]
    if len(moves) < MIN_RATE_MOVES:
        return Estimate("alpha_rate_dps", params.alpha_rate_dps, float("nan"), False,
                        f"needs commands that step further than the gear moves in one sample period "
                        f"({len(moves)} such steps seen, {MIN_RATE_MOVES} needed)")
    rates = moves / dts
    spread = float(np.std(rates, ddof=1)) if len(rates) > 1 else 0.0
    resolution = 1e-4 / float(np.mean(dts))  # the angle is sent as float32: about 1e-4 deg near 100 deg
    half_width = Z95 * max(spread / np.sqrt(len(rates)), resolution)
    return Estimate("alpha_rate_dps", float(np.mean(rates)), half_width, True)


def sensor_depth_limit_m(params: PlantParams) -> float:
    """The deepest depth the pressure sensor still measures, less a centimetre (its noise, the conversion)."""
    rho_g = params.water_density_kgpm3 * params.gravity_mps2
    return (params.pressure_max_pa - params.surface_pressure_pa) / rho_g - 0.01


def _trim_guess(params: PlantParams, windows: Windows) -> float:
    """The trim at which the median recorded gear angle is neutral: a start the fit converges from."""
    neutral = float(np.median(windows.alpha_deg))
    return (0.5 - neutral / params.alpha_max_deg) / _neutral_per_trim(params) * params.alpha_max_deg


def fit_recordings(paths: Iterable[str | Path], base: PlantParams, window_s: float = 10.0,
                   on_eval: EvalHook | None = None, on_read: ReadHook | None = None) -> FitResult:
    """Fit base's plant to the recordings: the figures they identify replaced, the rest kept."""
    started = time.perf_counter()
    if not window_s > 0:
        raise FitError(f"--window must be positive (got {window_s})")
    result = fit_samples(read_samples(paths, on_read), base, window_s, on_eval)
    result.wall_s = time.perf_counter() - started
    return result


def predict_recordings(paths: Iterable[str | Path], params: PlantParams,
                       window_s: float = 30.0) -> tuple[Windows, NDArray[np.float64]]:
    """How well a plant predicts recordings it was not fitted to: the depth RMS error of each window, the plant
    run open loop under the recorded commands. Only each window's start depth and velocity (which no recording
    holds exactly) are fitted; every figure of the plant is held."""
    windows = cut_windows(read_samples(paths), window_s, sensor_depth_limit_m(params))
    hull = fit_hull(params, windows, ())
    owner = windows.owner()
    squares = (windows.depth_m - hull.predicted_m) ** 2
    return windows, np.sqrt(np.bincount(owner, squares) / np.bincount(owner))


def fit_samples(samples: Samples, base: PlantParams, window_s: float = 10.0,
                on_eval: EvalHook | None = None) -> FitResult:
    """fit_recordings on samples already read."""
    windows = cut_windows(samples, window_s, sensor_depth_limit_m(base))
    rate = fit_rate(base, windows)
    params = replace(base, alpha_rate_dps=rate.value) if rate.identified else base
    params = replace(params, trim_error_fraction=_trim_guess(params, windows))
    free = list(HULL_FIELDS)
    limits = _limits(params)
    hull = fit_hull(params, windows, free, on_eval)
    # Figures the data cannot pin down are kept at the base's value and the rest fitted again without them:
    # a free but unidentifiable figure would trade off against the others and widen their intervals.
    loose = [name for name in free if not hull.half_width(name) <= limits[name]]
    if loose:
        kept = {name: getattr(base, name) for name in loose}
        free = [name for name in free if name not in loose]
        hull = fit_hull(replace(hull.params, **kept), windows, free, on_eval, (hull.z0_m, hull.v0_mps))
    estimates = [rate]
    for name in HULL_FIELDS:
        if name in free:
            estimates.append(Estimate(name, getattr(hull.params, name), hull.half_width(name), True))
        else:
            estimates.append(Estimate(name, getattr(base, name), float("nan"), False, _needs(name, windows)))
    trim = next(e for e in estimates if e.name == "trim_error_fraction")
    estimates.append(Estimate(NEUTRAL, neutral_alpha_deg(hull.params), trim.half_width * _neutral_per_trim(params),
                              trim.identified, trim.needs))
    estimates.append(_noise(hull, params))
    fitted = replace(hull.params, pressure_noise_pa=estimates[-1].value)
    return FitResult(params=fitted, estimates=estimates, residual_rms_m=hull.residual_rms_m, windows=windows,
                     hull=hull, files=samples.files, notes=samples.notes)


def _noise(hull: HullFit, params: PlantParams) -> Estimate:
    """The sensor's noise RMS in Pa: the fit's residual, less the 0.01 mbar quantisation's share."""
    rho_g = params.water_density_kgpm3 * params.gravity_mps2
    total_pa = hull.residual_rms_m * rho_g
    noise_pa = float(np.sqrt(max(total_pa**2 - params.pressure_lsb_pa**2 / 12.0, 0.0)))
    # The variance of an RMS from n residuals: sigma / sqrt(2 n).
    return Estimate("pressure_noise_pa", noise_pa, Z95 * total_pa / np.sqrt(2.0 * hull.dof), True)
