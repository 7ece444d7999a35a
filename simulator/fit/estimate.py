"""The whole fit: actuator rate and dead band from the gear's own record, the hull, backlash and pressure lag by
least squares of the depth, the sensor's noise and its colour from the residuals, the residuals' diagnostics
(intervals widened where they fail), and which figures the data could identify (and what would identify the
others)."""

from __future__ import annotations

import time
from collections.abc import Iterable
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import brentq
from scipy.stats import norm

from protocol import Mode
from simulator.fit.model import HULL_FIELDS, Z95, EvalHook, HullFit, fit_hull
from simulator.fit.reader import FitError, ReadHook, Samples, read_samples
from simulator.fit.residuals import MAX_PHI, colour_estimate, diagnose, lag1_phi, noise_estimate
from simulator.fit.residuals import Diagnostic as Diagnostic  # part of FitResult's interface
from simulator.fit.residuals import Estimate as Estimate
from simulator.fit.windows import Windows, cut_windows
from simulator.parameters import PlantParams, neutral_alpha_deg

NEUTRAL = "neutral_angle_deg"  # reported beside trim_error_fraction, which it is a function of
# The hand-over offset as recorded holds the recovery controller's own averaging error on top of any extra trim
# error, and a study on the fitted plant simulates that controller itself: reported, not written as a figure.
HANDOVER = "handover_offset_deg"
REPORTED_ONLY = (NEUTRAL, HANDOVER)
MIN_RATE_MOVES = 5  # saturated gear moves needed to measure the actuator's rate
MIN_DEAD_BAND_PAIRS = 20  # held commands the motor did (and did not) follow, needed to bracket the dead band
# Where the least squares starts the gear's play and the port's lag: off 0, where |x| has no slope to leave by.
START_BACKLASH_DEG, START_LAG_S = 0.5, 0.05
RESTARTS = ((1.5, 0.15), (0.1, 0.01))  # (backlash, lag) starts when the first joint fit is lost
GEAR_AND_PORT = ("backlash_deg", "pressure_lag_s")
# The depth-scale error no recording of depth identifies (water 5-30 C, the sensor's span: docs/families/tank.toml
# draws +/- 1 %); intervals admit what it could do to each figure.
DEPTH_SCALE_RANGE = 0.01
PHI_TOLERANCE = 0.005  # a re-estimated AR(1) further off than this is fitted again (near 1 a little matters)
NEEDED_CHI2 = 6.63  # chi-square(1) 99 % point: fixing a loose figure costs more than this, it stays free
MIN_EPISODES = 5  # learning episodes' starts needed to measure the hand-over offset
# Why a figure wider than its limit stays in the fit: (any figure, the gear's play and the port's lag).
KEPT_BECAUSE = ("fixing it worsens the fit", "the base's 0 is no robot's value: fixed, it would bias the others")


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
    diagnostics: list[Diagnostic] = field(default_factory=list)
    robust: bool = False  # a diagnostic failed (the intervals are the sandwich's wherever wider, failed or not)

    @property
    def warning(self) -> str:
        """One line when a diagnostic failed, else empty."""
        failed = [d.name for d in self.diagnostics if not d.passed]
        if not failed:
            return ""
        return (f"warning: the residuals fail {' and '.join(failed)}: the model misses something the recording "
                f"shows; the intervals (the wider of the Jacobian's and the sandwich's over {self.windows.count} "
                f"windows) hold for misfit that differs from window to window, not for one common to all")

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
        "backlash_deg": 0.2,  # issue 42's goal
        "pressure_lag_s": 0.02,  # issue 42's goal: a step of the 40 Hz loop
    }


def _needs(name: str, windows: Windows) -> str:
    speed = np.abs(np.diff(windows.depth_m)) / np.maximum(np.diff(windows.t_s), 1e-9)
    span = float(np.ptp(windows.depth_m))
    step = float(np.ptp(windows.cmd_deg))
    reach_cmps = 100 * np.percentile(speed, 99)
    return {
        "added_mass_kg": f"needs steps of the actuator command (the commands span {step:.1f} deg): `dive fit --excite` "
                         "with --depths further apart",
        "drag_kgpm": f"needs speeds above 5 cm/s (the recordings reach about {reach_cmps:.1f} cm/s): `dive fit "
                     "--excite` with --depths further apart",
        "trim_error_fraction": "needs time hovering at a steady depth: `dive fit --excite` with a longer --hold "
                               "(or `dive hover`)",
        "compressibility_m3pm": f"needs hovering at depths at least 0.5 m apart (the recordings span {span:.2f} m): "
                                "`dive fit --excite --depths 0.3,0.9,0.3`",
        "backlash_deg": "needs reversals of the actuator command at several amplitudes while the hull moves: `dive "
                        "fit --excite` with larger or longer reversals of the hover depth (--reversals "
                        "0.05,0.1,0.2 --reversal-hold 5)",
        "pressure_lag_s": "needs fast steps of the actuator command of several sizes (the phase between gear and "
                          "depth): `dive fit --excite` with its reversals of the hover depth (--reversals "
                          "0.02,0.05,0.1, more of them: several recordings)",
    }[name]


# Figures the simulator has that no recording of depth and gear can tell apart from others: what would.
UNIDENTIFIABLE = {
    "pressure_bias_pa": "not identifiable from these recordings, needs a reading at a known depth: a constant "
                        "depth offset looks like another start depth in every window (the firmware's P0, taken "
                        "at rest at the surface, cancels it)",
    "pressure_drift_pa_per_s": "not identifiable from these recordings, needs readings at a known depth hours "
                               "apart (at rest at the surface before and after a long run)",
    "depth_scale_error": "not identifiable from these recordings, needs a depth difference known without this "
                         "sensor (`dive hover` at two depths marked on the tank wall): a scaled depth looks like a "
                         "scaled inertia and drag (intervals admit +/- --depth-scale of it)",
}


def _held_pairs(params: PlantParams, windows: Windows) -> tuple[NDArray[np.float64], NDArray[np.float64],
                                                                  NDArray[np.float64]]:
    """(gap to the command at a sample, the motor's move to the next sample, the interval) for consecutive
    samples of one window: the command recorded with a sample is the one held until the next."""
    owner = windows.owner()
    same = owner[1:] == owner[:-1]
    target = np.clip(windows.cmd_deg[:-1], 0.0, params.alpha_max_deg)
    gap = (target - windows.alpha_deg[:-1])[same]
    move = np.diff(windows.alpha_deg)[same]
    return gap, move, np.diff(windows.t_s)[same]


def fit_dead_band(params: PlantParams, windows: Windows) -> Estimate:
    """The stepper's dead band, bracketed by the counted angle: it stays put for a held command within half the
    band and moves for one outside it. Half the band lies between the largest gap it stayed put for and the
    smallest it moved for; the estimate is the bracket's middle, its half-width the bracket's."""
    gap, move, _ = _held_pairs(params, windows)
    still = move == 0.0  # float32 counts: an unmoved stepper reports the same bits
    stayed = np.abs(gap[still])
    moved = np.abs(gap[~still & (np.abs(gap) > 0.0)])
    if len(stayed) < MIN_DEAD_BAND_PAIRS or len(moved) < MIN_DEAD_BAND_PAIRS:
        return Estimate("dead_band_deg", params.dead_band_deg, float("nan"), False,
                        f"needs held commands the stepper did and did not follow ({len(stayed)} and {len(moved)} "
                        f"seen, {MIN_DEAD_BAND_PAIRS} each needed): small command changes, as hovering gives")
    low, high = float(stayed.max()), float(moved.min())
    if high <= low:  # the motor moved for a gap it stayed put for elsewhere: no dead band explains both
        high = low
    return Estimate("dead_band_deg", low + high, max(high - low, 2e-5), True)


def fit_rate(params: PlantParams, windows: Windows, half_dead_deg: float = 0.0) -> Estimate:
    """The stepper's top rate, from sample intervals where the gear could not reach its command."""
    gap, move, dt = _held_pairs(params, windows)
    # Saturated: moved toward the command, by a visible amount, and still outside the dead band at the end
    # (a motor that stopped at the band's edge did not move at its top rate the whole interval).
    saturated = ((np.sign(move) == np.sign(gap)) & (np.abs(move) > 0.05)
                 & (np.abs(move) < np.abs(gap) - half_dead_deg - 0.01))
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
                   on_eval: EvalHook | None = None, on_read: ReadHook | None = None,
                   depth_scale: float = DEPTH_SCALE_RANGE) -> FitResult:
    """Fit base's plant to the recordings: the figures they identify replaced, the rest kept."""
    started = time.perf_counter()
    if not window_s > 0:
        raise FitError(f"--window must be positive (got {window_s})")
    if not 0.0 <= depth_scale < 0.5:
        raise FitError(f"--depth-scale must lie within 0 .. 0.5 (got {depth_scale})")
    result = fit_samples(read_samples(paths, on_read), base, window_s, on_eval, depth_scale)
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
                on_eval: EvalHook | None = None, depth_scale: float = DEPTH_SCALE_RANGE) -> FitResult:
    """fit_recordings on samples already read; depth_scale: the sensor's depth-scale error is taken to lie
    within +/- this, and every interval admits what it could shift a figure by."""
    windows = cut_windows(samples, window_s, sensor_depth_limit_m(base))
    dead = fit_dead_band(base, windows)
    params = replace(base, dead_band_deg=dead.value) if dead.identified else base
    rate = fit_rate(params, windows, 0.5 * params.dead_band_deg)
    params = replace(params, alpha_rate_dps=rate.value) if rate.identified else params
    params = replace(params, trim_error_fraction=_trim_guess(params, windows))
    free = list(HULL_FIELDS)
    limits = _limits(params)
    # The gear's play and the port's lag make the cost rough far from the optimum: the hull alone first (as
    # smooth as the ideal plant's), then everything from there, prewhitened by the noise's AR(1) as the hull's
    # residuals show it (generalised least squares: the Jacobian's intervals hold under coloured noise, ordinary
    # least squares' are too narrow). A joint fit worse than the hull's alone is a lost optimiser, tried again
    # from other starts of the two, the best kept.
    hull_only = [name for name in free if name not in GEAR_AND_PORT]
    first = fit_hull(replace(params, backlash_deg=0.0, pressure_lag_s=0.0), windows, hull_only, on_eval)
    phi = min(max(lag1_phi(first, windows)[0], 0.0), MAX_PHI)
    hull = first
    for backlash, lag in ((START_BACKLASH_DEG, START_LAG_S), *RESTARTS):
        again = fit_hull(replace(first.params, backlash_deg=backlash, pressure_lag_s=lag), windows, free, on_eval,
                         (first.z0_m, first.v0_mps), phi)
        if hull is first or again.residual_rms_m < hull.residual_rms_m:
            hull = again
        if hull.residual_rms_m <= first.residual_rms_m * (1.0 + 1e-3):  # no worse than the hull alone
            break
    # Once more if the joint fit's residuals show another colour (the hull alone shows the gear's and the port's
    # misfit as colour too): iterated Cochrane-Orcutt, the second pass is the last needed in practice.
    for _ in range(2):
        again_phi = min(max(lag1_phi(hull, windows)[0], 0.0), MAX_PHI)
        if abs(again_phi - phi) <= PHI_TOLERANCE:
            break
        phi = again_phi
        hull = fit_hull(hull.params, windows, free, on_eval, (hull.z0_m, hull.v0_mps), phi)
    diagnostics = diagnose(hull, windows)
    robust = not all(d.passed for d in diagnostics)
    # Figures the data cannot pin down are kept at the base's value and the rest fitted again without them:
    # a free but unidentifiable figure would trade off against the others and widen their intervals. One at a
    # time, the loosest against its limit first: once it is out, the others it traded with may be pinned. A
    # figure the recording needs all the same (fixing it costs more than chi-square's 1 % point: a gear's play
    # under slow noise, say) stays in the fit, reported not identified: fixed, it would bias all the others.
    # The gear's play and the port's lag are never fixed: the base's 0 is no robot's value, and a play of 0.6 deg
    # fixed at 0 passed that test yet biased the drag by 1.3-1.6 of its half-widths (the family's draws).
    needed: list[str] = []
    while True:
        ratios = {name: _half_width(hull, name) / limits[name] for name in free if name not in needed}
        loosest = max(ratios, key=lambda name: ratios[name] if np.isfinite(ratios[name]) else np.inf, default="")
        if not loosest or ratios[loosest] <= 1.0:
            break
        if loosest in GEAR_AND_PORT:  # always needed (above)
            needed.append(loosest)
            continue
        rest = [name for name in free if name != loosest]
        fixed = fit_hull(replace(hull.params, **{loosest: getattr(base, loosest)}), windows, rest, on_eval,
                         (hull.z0_m, hull.v0_mps), phi)
        if fixed.cost - hull.cost > NEEDED_CHI2 * hull.cost / hull.dof:
            needed.append(loosest)
            continue
        free, hull = rest, fixed
        diagnostics = diagnose(hull, windows)
        robust = not all(d.passed for d in diagnostics)
    shift = _scale_shifts(hull, windows, free, phi, depth_scale)
    estimates = [rate, dead]
    for name in HULL_FIELDS:
        half_width = with_scale(_half_width(hull, name), shift[name]) if name in free else float("nan")
        if name in needed:
            estimates.append(Estimate(name, getattr(hull.params, name), half_width, False,
                                      f"fitted {getattr(hull.params, name):.4g} +/- {half_width:.3g}, wider than "
                                      f"{limits[name]:g}: kept in the fit ({KEPT_BECAUSE[name in GEAR_AND_PORT]}), "
                                      + _needs(name, windows), in_fit=True))
        elif name in free:
            estimates.append(Estimate(name, getattr(hull.params, name), half_width, True))
        else:
            estimates.append(Estimate(name, getattr(base, name), float("nan"), False, _needs(name, windows)))
    trim = next(e for e in estimates if e.name == "trim_error_fraction")
    estimates.append(Estimate(NEUTRAL, neutral_alpha_deg(hull.params), trim.half_width * _neutral_per_trim(params),
                              trim.identified, trim.needs))
    noise = noise_estimate(hull, windows, params)
    noise = replace(noise, half_width=with_scale(noise.half_width, depth_scale * noise.value))
    estimates.append(noise)
    estimates.append(colour_estimate(hull, windows, params, noise.value))
    estimates.append(_handover(samples, hull.params, estimates[-3]))
    estimates.extend(Estimate(name, getattr(base, name), float("nan"), False, needs)
                     for name, needs in UNIDENTIFIABLE.items())
    figures: dict[str, Any] = {e.name: e.value for e in estimates
                               if (e.identified or e.in_fit) and e.name not in REPORTED_ONLY}
    fitted = replace(hull.params, **{name: value for name, value in figures.items() if hasattr(hull.params, name)})
    return FitResult(params=fitted, estimates=estimates, residual_rms_m=hull.residual_rms_m, windows=windows,
                     hull=hull, files=samples.files, notes=samples.notes, diagnostics=diagnostics, robust=robust)


def _scale_shifts(hull: HullFit, windows: Windows, free: list[str], phi: float,
                  depth_scale: float) -> dict[str, float]:
    """What a depth-scale error of depth_scale shifts each free figure by: a depth read (1 + s) times too large
    is a hull (1 + s) times lighter to the fit (inertia and drag scale with it) and no recording of depth alone
    tells them apart. The fit again on the depth so scaled gives the slope."""
    if depth_scale == 0.0 or not free:
        return dict.fromkeys(free, 0.0)
    scaled = replace(windows, depth_m=windows.depth_m * (1.0 + depth_scale))
    again = fit_hull(hull.params, scaled, free, None, (hull.z0_m * (1.0 + depth_scale), hull.v0_mps), phi)
    return {name: abs(getattr(again.params, name) - getattr(hull.params, name)) for name in free}


def _half_width(hull: HullFit, name: str) -> float:
    """The statistical 95 % half-width: the larger of the Jacobian's and the bias-reduced sandwich's over windows.
    The Jacobian's holds when the model is the truth; the sandwich's when it is not, whatever the diagnostics say
    (on the C plant the drag's error, the depth scale's share taken off, exceeded the Jacobian's interval in 4 of
    23 of the family's draws with both diagnostics passed)."""
    return max(hull.half_width(name), hull.half_width(name, robust=True))


def with_scale(half_width: float, shift: float) -> float:
    """A 95 % half-width that holds for every depth-scale error within the bound: the statistical half-width
    (its normal-equivalent sigma) beside a systematic shift of at most `shift` either way. The interval must
    cover the worst case, the shift at its bound: P(|sigma Z + shift| <= q) = 0.95. Quadrature (the shift as
    one more random term) covers it only where one of the two dominates; the family's draws found added mass
    and drag inside in 79 % of them that way."""
    sigma = half_width / Z95
    if not shift > 0.0 or not np.isfinite(half_width):
        return half_width
    if sigma <= 0.0:
        return shift

    def short(q: float) -> float:
        return float(norm.cdf((q - shift) / sigma) - norm.cdf((-q - shift) / sigma)) - 0.95

    low, high = max(half_width, shift), shift + half_width
    if short(low) >= 0.0 or short(high) <= 0.0:  # one term dominates: the bracket's end is the answer in floats
        return low if short(low) >= 0.0 else high
    return float(brentq(short, low, high, xtol=1e-9 * high))


def _handover(samples: Samples, params: PlantParams, trim: Estimate) -> Estimate:
    """The learner's hand-over offset: where each learning episode's actuator window was
    centred (its first command) against the fitted neutral angle, averaged over the episodes."""
    first = np.flatnonzero(samples.episode_start & (samples.mode == Mode.LEARNING))
    if len(first) < MIN_EPISODES or not trim.identified:
        return Estimate(HANDOVER, 0.0, float("nan"), False,
                        f"needs learning episodes (`dive run`; {len(first)} seen, {MIN_EPISODES} needed): each "
                        "episode's first command against the fitted neutral angle")
    offsets = samples.cmd_deg[first] - neutral_alpha_deg(params)
    spread = float(np.std(offsets, ddof=1)) / np.sqrt(len(offsets))
    return Estimate(HANDOVER, float(np.mean(offsets)), Z95 * spread + trim.half_width, True)
