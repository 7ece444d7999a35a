"""The fit's residuals: the sensor noise and its AR(1) colour they show, and the two checks of them (magnitude
against the noise the depth itself shows, whiteness after the AR(1)); each window's residuals kept apart."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.stats import chi2
from scipy.stats import t as student_t

from simulator.fit.model import Z95, HullFit
from simulator.fit.windows import Windows
from simulator.parameters import PlantParams

LJUNG_BOX_LAGS = 10
WHITE_P = 0.01  # Ljung-Box p-value below which the prewhitened residuals are not white ..
WHITE_RHO = 0.05  # .. if an autocorrelation is also this large (24000 samples find 0.02, which costs nothing)
MAGNITUDE_LIMIT = 1.25  # residual RMS against the sensor noise the depth's own second differences show
MAX_PHI = 0.99  # a lag-1 autocorrelation nearer 1 than this is drift, not noise: prewhitening stops there


@dataclass(frozen=True)
class Estimate:
    """One fitted figure (a PlantParams field, or the neutral angle derived from the trim)."""

    name: str
    value: float
    half_width: float  # of the 95 % interval; nan when not identified
    identified: bool
    needs: str = ""  # when not identified: the excitation that would identify it
    in_fit: bool = False  # not identified, but free in the fit and written (fixed, it would bias the others)


@dataclass(frozen=True)
class Diagnostic:
    """One check of the residuals: passed, and its line."""

    name: str
    passed: bool
    line: str


def window_sums(hull: HullFit, windows: Windows, lag: int = 0,
                 phi: float = 0.0) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per window: sum of u_t u_{t-lag} and of u_t^2, u the residuals (prewhitened by phi when given)."""
    r = hull.residuals_m
    owner = windows.owner()
    u = r.copy()
    same1 = np.zeros(len(r), dtype=np.bool_)
    same1[1:] = owner[1:] == owner[:-1]
    if phi != 0.0:
        u[1:] = np.where(same1[1:], r[1:] - phi * r[:-1], np.nan)
        u[~same1] = np.nan
    valid = ~np.isnan(u)
    squares = np.asarray(np.bincount(owner[valid], u[valid] ** 2, minlength=windows.count), dtype=np.float64)
    if lag == 0:
        return squares, squares
    pair = np.zeros(len(r), dtype=np.bool_)
    pair[lag:] = (owner[lag:] == owner[:-lag]) & valid[lag:] & valid[:-lag]
    products = np.zeros(len(r))
    products[lag:] = np.where(pair[lag:], np.nan_to_num(u[lag:]) * np.nan_to_num(u[:-lag]), 0.0)
    return np.asarray(np.bincount(owner, products, minlength=windows.count), dtype=np.float64), squares


def lag1_phi(hull: HullFit, windows: Windows) -> tuple[float, float]:
    """The residuals' lag-1 autocorrelation and its standard error, clustered over windows (a ratio estimator
    linearised: robust to whatever else the residuals carry window by window)."""
    products, squares = window_sums(hull, windows, 1)
    rho = float(products.sum() / squares.sum())
    g = windows.count
    se = float(np.sqrt(np.sum((products - rho * squares) ** 2) * g / max(g - 1, 1)) / squares.sum())
    # Each window's fitted start depth and velocity take a level and a slope out of the noise, which pulls its
    # autocorrelation down: by (1 + 4 rho) / n for a level alone (Kendall), about twice that for both. Added
    # back, with half of it kept as uncertainty (the hull's figures take a little more, unmodelled).
    n_w = float(np.mean(windows.ends - windows.starts))
    bias = (2.0 + 8.0 * max(rho, 0.0)) / n_w
    return rho + bias, float(np.hypot(se, 0.5 * bias))


def hfnoise_estimate(windows: Windows, phi: float) -> float:
    """The sensor noise RMS the depth itself shows: its second differences (the hull's motion adds under 1 % to
    them at 40 Hz), scaled for AR(1) noise of lag-1 autocorrelation phi. A model that misses something leaves
    a residual above it; one that fits, a residual of about the same size."""
    owner = windows.owner()
    d = windows.depth_m
    ok = owner[2:] == owner[:-2]
    second = (d[2:] - 2.0 * d[1:-1] + d[:-2])[ok]
    # var(second difference) = sigma^2 (6 - 8 phi + 2 phi^2) for AR(1) noise.
    return float(np.sqrt(np.mean(second**2) / (6.0 - 8.0 * phi + 2.0 * phi * phi)))


def diagnose(hull: HullFit, windows: Windows) -> list[Diagnostic]:
    """Magnitude (the residual against the noise the depth shows) and whiteness (Ljung-Box over the residuals
    prewhitened by the AR(1) noise the fit assumed)."""
    phi = hull.phi
    hf = hfnoise_estimate(windows, phi)
    ratio = hull.residual_rms_m / hf if hf > 0 else float("inf")
    magnitude = Diagnostic("magnitude", ratio <= MAGNITUDE_LIMIT,
                           f"magnitude: residual RMS {1000 * hull.residual_rms_m:.3f} mm against the sensor noise "
                           f"the depth shows {1000 * hf:.3f} mm: {ratio:.2f}x (a model that fits: about 1, limit "
                           f"{MAGNITUDE_LIMIT})")
    n = int(np.sum(windows.ends - windows.starts)) - windows.count
    rhos = []
    for k in range(1, LJUNG_BOX_LAGS + 1):
        products, squares = window_sums(hull, windows, k, phi)
        rhos.append(float(products.sum() / squares.sum()))
    q = n * (n + 2) * sum(r * r / max(n - k, 1) for k, r in enumerate(rhos, start=1))
    p_value = float(chi2.sf(q, LJUNG_BOX_LAGS))
    worst = max(abs(r) for r in rhos)
    white = Diagnostic("whiteness", not (p_value < WHITE_P and worst > WHITE_RHO),
                       f"whiteness: residuals prewhitened by their AR(1) {phi:.3f}: Ljung-Box Q({LJUNG_BOX_LAGS}) = "
                       f"{q:.0f}, p = {p_value:.2g}, largest |autocorrelation| {worst:.3f} (white: p >= {WHITE_P} "
                       f"or every one below {WHITE_RHO})")
    return [magnitude, white]


def noise_estimate(hull: HullFit, windows: Windows, params: PlantParams) -> Estimate:
    """The sensor's noise RMS in Pa: the fit's residual, less the 0.01 mbar quantisation's share; its interval
    from the windows' own mean squares (clustered: holds for coloured noise) and from the noise's colour, which
    the correction for the fitted starts is only as good as."""
    rho_g = params.water_density_kgpm3 * params.gravity_mps2
    lengths = (windows.ends - windows.starts).astype(np.float64)
    rho, rho_se = lag1_phi(hull, windows)  # the final fit's own colour, not the one it assumed

    def corrected_pa(phi: float) -> float:
        # Each window's fitted start depth and velocity take up the noise's slow part too: with AR(1) noise a
        # fitted level or slope is worth (1 + phi) / (1 - phi) samples, not one (the variance of a correlated mean).
        phi = min(max(phi, 0.0), MAX_PHI)
        taken = len(hull.free) + 2.0 * windows.count * (1.0 + phi) / (1.0 - phi)
        dof = max(lengths.sum() - taken, 0.5 * lengths.sum())
        total_pa = hull.residual_rms_m * np.sqrt(hull.dof / dof) * rho_g
        return float(np.sqrt(max(total_pa**2 - params.pressure_lsb_pa**2 / 12.0, 0.0)))

    noise_pa = corrected_pa(rho)
    squares, _ = window_sums(hull, windows)
    mean_square = squares.sum() / lengths.sum()
    g = windows.count
    se_ms = np.sqrt(np.sum((squares - mean_square * lengths) ** 2) * g / max(g - 1, 1)) / lengths.sum()
    # sd(sigma) = sd(sigma^2) / (2 sigma); never narrower than white noise's sigma / sqrt(2 n)
    se_pa = max(float(se_ms) / (2.0 * np.sqrt(mean_square)), np.sqrt(mean_square) / np.sqrt(2.0 * hull.dof)) * rho_g
    # The spread of g windows' mean squares is itself uncertain: Student's t over g - 1, not the normal's 1.96
    # (the family's draws found the normal's interval holding the truth in 67-83 % of them). Half of the slow
    # noise's correction is kept as uncertainty too: the prewhitened fit's starts take a little less than OLS's.
    # And the correction moves with the colour, whose own 95 % interval it is carried through: near phi = 1 a
    # little error in phi is much correction (the family's misses were noise of 0.38-0.42 s correlation taken
    # for 0.57-0.66 s).
    quantile = float(student_t.ppf(0.975, max(g - 1, 1)))
    correction_pa = noise_pa - hull.residual_rms_m * rho_g
    colour_pa = 0.5 * abs(corrected_pa(rho + Z95 * rho_se) - corrected_pa(rho - Z95 * rho_se))
    half_width = float(np.sqrt((quantile * se_pa) ** 2 + (0.5 * correction_pa) ** 2 + colour_pa**2))
    return Estimate("pressure_noise_pa", noise_pa, half_width, True)


def corr_time_interval(rho: float, se: float, white_share: float, dt_s: float) -> tuple[float, float]:
    """An AR(1) noise's correlation time and its 95 % half-width, from the lag-1 autocorrelation rho (standard error
    se) of samples dt_s apart, scaled by white_share (the quantisation's white part taken out); inf when rho's
    interval reaches 1 (longer than the windows can show)."""

    def corr_s(f: float) -> float:
        return 0.0 if f <= 0.0 else (float("inf") if f >= 1.0 else -dt_s / float(np.log(f)))

    low, mid, high = ((rho - Z95 * se) * white_share, rho * white_share, (rho + Z95 * se) * white_share)
    value, lo_s, hi_s = corr_s(mid), corr_s(low), corr_s(high)
    # Never narrower than the correlation the lag-1 test can tell from white at all (phi = 1.96 se): white noise's
    # fitted starts pull rho below 0, and a whole interval below 0 read as "0 s, +/- 0" (the tank family's draw 84
    # in issue 42's benchmark: a true 0.64 ms, its error infinitely many half-widths out).
    resolution_s = corr_s(min(Z95 * se * white_share, 0.5))
    return value, max(value - lo_s, hi_s - value, resolution_s)


def colour_estimate(hull: HullFit, windows: Windows, params: PlantParams, noise_pa: float) -> Estimate:
    """The noise's AR(1) correlation time from the residuals' lag-1 autocorrelation (the quantisation's white
    share taken out), at the recording's typical sample interval."""
    rho, se = lag1_phi(hull, windows)
    dt = float(np.median(np.diff(windows.t_s)[windows.owner()[1:] == windows.owner()[:-1]]))
    white_share = 1.0 + params.pressure_lsb_pa**2 / 12.0 / max(noise_pa, 1e-9) ** 2
    value, half_width = corr_time_interval(rho, se, white_share, dt)
    if not np.isfinite(half_width):
        return Estimate("pressure_noise_corr_s", params.pressure_noise_corr_s, float("nan"), False,
                        "needs longer windows than the noise's correlation (--window)")
    return Estimate("pressure_noise_corr_s", value, half_width, True)
