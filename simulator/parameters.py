"""Every physical figure of the simulated agent, with its source, and the presets `hardware` and `paper`."""

from __future__ import annotations

import dataclasses
import json
import math
import tomllib
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from learning.spec import KernelSpec, kernel_tuple_type, to_kernel_tuple
from simulator.errors import ParamsError

MAX_FILE_BYTES = 1024 * 1024  # a parameter or plant file is a few KiB


@dataclass(frozen=True)
class PlantParams:
    """Plant, actuator, sensor, observer, recovery controller and episode figures (SI, z down).

    Sources: F = firmware of the authors' experiment, D = their DICE MATLAB simulator,
    S = datasheet, P = the paper, E = our estimate, C = calibration of diving-agent.md s. 7.
    """

    # --- hull and water
    mass_kg: float = 0.3793  # F: m_c = 0.3793 (the paper's "approx. 200 g" disagrees with 3.7 %)
    added_mass_kg: float = 0.10  # E: 0.06-0.15 kg for a 70 mm cylinder; C uses 0.10
    water_density_kgpm3: float = 1000.0  # F: fresh water tank
    gravity_mps2: float = 9.81  # F
    trim_error_fraction: float = 0.0  # D: +1 % of V0 is typical; 0 = V0 = m / rho (F comment)
    compressibility_m3pm: float = 0.0  # E: hull volume lost per metre of depth; 0 = rigid hull
    drag_kgpm: float = 1.0  # F, D: F_D = k z' |z'| with k = 1 kg/m (textbook Cd 0.9 gives 1.7)
    floor_depth_m: float = 10.0  # P: rated to 10 m; a hard floor, the agent rests on it
    # --- diaphragm actuator
    stroke_volume_m3: float = 14.44e-6  # F: A_dia 707 mm^2 x h_max 20.42 mm
    alpha_max_deg: float = 130.0  # F: gear output range 0..130 deg, neutral at mid-stroke
    alpha_rate_dps: float = 35.2  # F: 500 full steps/s, 18 deg/step, 256:1 gear
    # The real actuator's imperfections (docs/robust-plant.md; 0 = the ideal actuator above).
    backlash_deg: float = 0.0  # E: gear output lost motion on reversal; robot 0..3 deg (256:1 spur train)
    dead_band_deg: float = 0.0  # E: the stepper stops within half of it short of the command; robot 0..1 deg
    # --- the learner's actuator interface
    control_period_s: float = 0.1  # F: RL loop period (P: 0.02-0.2 s)
    control_jitter_s: float = 0.0  # E: each learner step lasts the period +/- up to this (uniform); robot 0..0.01 s
    action_step_deg: float = 2.1  # F: alpha_cmd -/+ 2.1 deg per RL step
    action_window_deg: float = 19.5  # F: alpha_cmd clipped to alpha_avg +/- 19.5 deg (+/- 2.17 ml)
    # --- integration
    substep_s: float = 0.005  # C: semi-implicit Euler at 5 ms (s. 2: at most 5 ms)
    # Issue 43: the same sub-steps summed over a control period in closed form (simulator/plant/kernel.py), for
    # studies outside the paper's reproduction; depth within 0.1 mm of the sub-steps' over 300 s on every plant
    # (s. 2's rule; tests/simulator/plant/test_closed_form.py).
    closed_form_step: bool = False
    # Issue 43: the study's trial loop compiled with LLVM's fast-math flags simulator/study/kernel.FAST_MATH_FLAGS
    # (reciprocals, fused multiply-adds, reassociation): other last bits, for studies outside the paper's reproduction.
    fast_arithmetic: bool = False
    # --- pressure sensor MS5803-01BA
    surface_pressure_pa: float = 101325.0  # standard atmosphere (F: P0 measured at start)
    pressure_noise_pa: float = 6.5  # S: 0.065 mbar RMS at OSR 256 = 0.66 mm of water
    pressure_lsb_pa: float = 1.0  # S: output resolution 0.01 mbar
    pressure_min_pa: float = 1000.0  # S: range 10 mbar ..
    pressure_max_pa: float = 130000.0  # S: .. 1300 mbar, about 2.9 m of water
    # The real sensor's imperfections (docs/robust-plant.md; 0 = the ideal sensor above).
    pressure_bias_pa: float = 0.0  # E: offset of every reading (P0 taken at a wavy surface); robot -100..100 Pa
    pressure_drift_pa_per_s: float = 0.0  # E: the offset grows with plant time (weather, warm-up); robot +/-0.03
    pressure_lag_s: float = 0.0  # E: first-order lag of the sensed depth behind the true one; robot 0..0.3 s
    pressure_noise_corr_s: float = 0.0  # E: AR(1) noise correlation time (0 = white); robot 0..1 s
    depth_scale_error: float = 0.0  # E: sensed depth = true depth x (1 + this) (water density, span); +/-0.03
    # Issue 43: the noise drawn by the ziggurat (learning/rng.normal_ziggurat, ~3.5x cheaper than Box-Muller), for
    # studies outside the paper's reproduction: the same normal distribution, another sequence from the same seed.
    ziggurat_noise: bool = False
    # --- sliding mode velocity observer (diving-agent.md s. 3)
    use_observer: bool = True  # F: the agent measures depth only; False feeds the true velocity
    observer_rho_mps: float = 2.5  # F
    observer_tau_s: float = 0.2  # F
    observer_phi_m: float = 0.5  # F
    # --- recovery controller (diving-agent.md s. 4)
    recovery_period_s: float = 0.025  # F
    recovery_lambda_per_s: float = 0.4  # F: sliding surface s = e' + lambda e
    recovery_phi_mps: float = 0.5  # F: boundary layer
    recovery_gain_deg: float = 65.0  # E: full half-stroke at the edge of the boundary layer
    recovery_avg_time_s: float = 10.0  # E: time constant of the running mean alpha_avg
    # An inner, steeper boundary layer that takes up the gear's lost motion on each reversal of s (0 = off).
    recovery_near_gain_deg: float = 0.0  # E: extra gear angle at the edge of the inner layer; ~ the backlash
    recovery_near_phi_mps: float = 0.01  # E: inner boundary layer of s (the settle band's velocity)
    settle_depth_m: float = 0.01  # F: hand over when |e| < 0.01 m ..
    settle_velocity_mps: float = 0.01  # F: .. and |z'| < 0.01 m/s ..
    settle_time_s: float = 6.25  # F: .. for 6.25 s
    give_up_s: float = 100.0  # F: the recovery controller gives up after 100 s
    # --- episodes
    target_depth_m: float = 0.4  # P: experiment z_d = 0.4 m (simulation does not say; any depth works)
    episode_limit_s: float = 300.0  # P: 300 s in the region counts as success
    start_with_recovery: bool = True  # F: the recovery controller brings the agent to a random depth
    start_depth_fraction: float = 0.95  # C: start depth ~ U(+/- 0.95 z_tol) around the target
    start_trim_error_deg: float = 0.0  # E: error of the learned neutral angle at hand-over


PlantSpec = kernel_tuple_type(PlantParams, "PlantSpec")

_PRESETS: dict[str, PlantParams] = {
    # The firmware figures with the observer in the loop and the recovery controller between episodes.
    # The inner boundary layer of the recovery controller (recovery_near_gain_deg) lets it settle despite up to
    # 3 deg of gear backlash (docs/robust-plant.md, "The recovery controller on a real gear").
    "hardware": PlantParams(trim_error_fraction=0.005, recovery_near_gain_deg=3.0),
    # Issue 43: the same plant with its 5 ms sub-steps summed in closed form (closed_form_step): depth within
    # 0.01 mm of the sub-steps' over 300 s on every plant variant, a study's plant at O(1) per control period.
    # For studies outside the paper's reproduction (diving-agent.md s. 2); the paper preset keeps its sub-steps.
    # It also draws the sensor's noise by the ziggurat (ziggurat_noise) and runs a study's trial loop in fast
    # arithmetic (fast_arithmetic).
    "hardware-fast": PlantParams(trim_error_fraction=0.005, recovery_near_gain_deg=3.0, closed_form_step=True,
                                 ziggurat_noise=True, fast_arithmetic=True),
    # Calibration P1 of diving-agent.md s. 7, which reproduces the paper's Fig. 5: a narrow actuator
    # window (+/- 6.5 deg) and slower step (1.625 deg) around the true neutral, the true velocity
    # to the learner (the paper names its observer only for the experiment), restarts at rest.
    "paper": PlantParams(
        action_step_deg=1.625,
        action_window_deg=6.5,
        use_observer=False,
        start_with_recovery=False,
    ),
}


def preset_names() -> list[str]:
    """Names accepted by preset()."""
    return sorted(_PRESETS)


def is_hardware(name: str) -> bool:
    """Whether a preset is the robot's plant (the hardware goals and both learning regions apply)."""
    return name in ("hardware", "hardware-fast")


def preset(name: str) -> PlantParams:
    """The named parameter set ("hardware", "hardware-fast" or "paper")."""
    try:
        return _PRESETS[name]
    except KeyError:
        raise ParamsError(f"unknown preset {name!r}; choose one of {', '.join(preset_names())}") from None


def with_overrides(params: PlantParams, overrides: dict[str, Any]) -> PlantParams:
    """params with the given fields replaced, type-checked against the dataclass."""
    fields = {f.name: f for f in dataclasses.fields(PlantParams)}
    clean: dict[str, Any] = {}
    for key, value in overrides.items():
        if key not in fields:
            raise ParamsError(f"unknown parameter {key!r}")
        kind = fields[key].type
        if kind == "bool":
            if not isinstance(value, bool):
                raise ParamsError(f"parameter {key!r} must be true or false")
        elif not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
            raise ParamsError(f"parameter {key!r} must be a finite number")
        clean[key] = value
    return validate(replace(params, **clean))


def _read_table(path: Path, key: str) -> dict[str, Any]:
    try:
        with path.open("rb") as f:
            text = f.read(MAX_FILE_BYTES + 1)  # bounded: `sim://?plant=/dev/zero` once grew to 20 GB (issue 38 N6)
    except OSError as e:
        raise ParamsError(f"cannot read parameter file {path}: {e}") from e
    if len(text) > MAX_FILE_BYTES:
        raise ParamsError(f"parameter file {path} is over {MAX_FILE_BYTES // 1024} KiB: not a parameter file")
    try:
        data = json.loads(text) if path.suffix.lower() == ".json" else tomllib.loads(text.decode())
    except UnicodeDecodeError:
        raise ParamsError(f"cannot read parameter file {path}: not UTF-8 text") from None
    except RecursionError:
        raise ParamsError(f"cannot read parameter file {path}: nested too deeply to be a parameter file") from None
    except ValueError as e:
        raise ParamsError(f"cannot read parameter file {path}: {e}") from e
    if not isinstance(data, dict):
        raise ParamsError(f"parameter file {path} must hold a table of {key} = value")
    return data


def read_param_table(path: Path, key: str = "field") -> dict[str, Any]:
    """The flat table of a TOML or JSON parameter file; `key` names its keys in the error (field, name)."""
    data = _read_table(path, key)
    plant = data.get("plant")
    # a fitted plant (`dive fit`) keeps its figures in [plant] (`dive run` hands that table to its simulator: --plant)
    if isinstance(plant, dict):
        data = {**{k: v for k, v in data.items() if k != "plant"}, **plant}
    return data


def read_plant_table(path: Path) -> dict[str, Any]:
    """A plant file's figures: its [plant] table (as `dive fit` writes it), or the whole file if it has none.

    What `dive run --params FILE` hands a simulator: the file's agent parameters go to the agent over the link.
    """
    data = _read_table(path, "field")
    plant = data.get("plant")
    return plant if isinstance(plant, dict) else data


def load_params(path: Path, base: PlantParams) -> PlantParams:
    """base with the overrides of a TOML or JSON file (a flat table of field = value)."""
    return with_overrides(base, read_param_table(path))


def validate(params: PlantParams) -> PlantParams:
    """params, or a ParamsError naming the first figure that cannot work."""
    positive = (
        "mass_kg", "water_density_kgpm3", "gravity_mps2", "stroke_volume_m3", "alpha_max_deg",
        "alpha_rate_dps", "control_period_s", "substep_s", "observer_tau_s", "observer_phi_m",
        "recovery_period_s", "recovery_phi_mps", "episode_limit_s", "floor_depth_m",
    )
    for name in positive:
        if getattr(params, name) <= 0:
            raise ParamsError(f"parameter {name!r} must be positive")
    if params.substep_s > params.control_period_s or params.substep_s > params.recovery_period_s:
        raise ParamsError("substep_s must not exceed the control periods")
    if params.added_mass_kg < 0 or params.drag_kgpm < 0 or params.pressure_noise_pa < 0:
        raise ParamsError("added mass, drag and noise must not be negative")
    for name in ("backlash_deg", "dead_band_deg", "control_jitter_s", "pressure_lag_s", "pressure_noise_corr_s"):
        if getattr(params, name) < 0:
            raise ParamsError(f"parameter {name!r} must not be negative")
    if params.control_jitter_s >= params.control_period_s - params.substep_s:
        raise ParamsError("control_jitter_s must be shorter than control_period_s less one substep_s")
    if params.depth_scale_error <= -0.5 or params.depth_scale_error >= 0.5:
        raise ParamsError("depth_scale_error must lie within -0.5 .. 0.5")
    return params


def kernel_params(params: PlantParams) -> KernelSpec:
    """The parameters as the named tuple the numba kernels take."""
    return to_kernel_tuple(params, PlantSpec)


def neutral_alpha_deg(params: PlantParams) -> float:
    """Gear angle at which the agent is neutrally buoyant at the surface (65 deg without trim error)."""
    fixed_volume_m3 = params.mass_kg / params.water_density_kgpm3 * (1.0 + params.trim_error_fraction)
    # m = rho (V_fixed + V_adj): V_adj = dV (alpha / alpha_max - 1/2).
    v_adj_m3 = params.mass_kg / params.water_density_kgpm3 - fixed_volume_m3
    return params.alpha_max_deg * (v_adj_m3 / params.stroke_volume_m3 + 0.5)
