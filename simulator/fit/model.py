"""Least squares of the compiled plant over the windows: the hull's figures shared, each window's start its own."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.optimize import least_squares
from scipy.sparse import csr_matrix

from simulator.fit.kernel import simulate_windows
from simulator.fit.windows import Windows
from simulator.parameters import PlantParams, kernel_params

# The hull's figures a fit may free, with the scale the optimiser sees them in (a typical size) and bounds.
HULL_FIELDS: dict[str, tuple[float, float, float]] = {
    "added_mass_kg": (0.1, 0.0, 2.0),
    "drag_kgpm": (1.0, 0.0, 50.0),
    "trim_error_fraction": (1e-3, -0.05, 0.05),
    "compressibility_m3pm": (1e-7, -1e-5, 1e-4),
}
_STATE_SCALE = (0.01, 0.01)  # z0 in cm, v0 in cm/s
_RESIDUAL_UNIT_M = 1e-3  # residuals in mm keep the cost near 1 for a good fit
_STEP = 1e-6  # finite-difference step, in the scaled units (each number's typical size)
Z95 = 1.959964  # two-sided 95 % normal quantile

EvalHook = Callable[[int, float], None]  # (evaluations so far, RMS residual in m)


@dataclass
class HullFit:
    """The fitted plant, its shared figures' covariance and the windows' fitted start states."""

    params: PlantParams
    free: tuple[str, ...]
    covariance: NDArray[np.float64]  # of the free figures, in their own units
    residual_rms_m: float
    dof: int  # samples minus fitted numbers
    z0_m: NDArray[np.float64]
    v0_mps: NDArray[np.float64]
    predicted_m: NDArray[np.float64]
    evaluations: int

    def half_width(self, name: str) -> float:
        """Half-width of the 95 % interval of a free figure (from the Jacobian at the optimum)."""
        i = self.free.index(name)
        return float(Z95 * np.sqrt(max(self.covariance[i, i], 0.0)))


def start_states(windows: Windows) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """First guesses of each window's depth and velocity: a line through its first half second."""
    z0 = np.empty(windows.count)
    v0 = np.empty(windows.count)
    for w, (a, b) in enumerate(zip(windows.starts, windows.ends, strict=True)):
        stop = a + 2
        while stop < b and windows.t_s[stop] - windows.t_s[a] < 0.5:
            stop += 1
        slope, offset = np.polyfit(windows.t_s[a:stop] - windows.t_s[a], windows.depth_m[a:stop], 1)
        z0[w], v0[w] = offset, slope
    return z0, v0


def simulate(params: PlantParams, windows: Windows, z0_m: NDArray[np.float64],
             v0_mps: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Depth and gear angle the plant predicts at every sample, each window from its start state."""
    depth = np.empty_like(windows.depth_m)
    alpha = np.empty_like(windows.depth_m)
    simulate_windows(kernel_params(params), windows.t_s, windows.cmd_deg, windows.alpha_deg[windows.starts],
                     windows.starts, windows.ends, z0_m, v0_mps, depth, alpha)
    return depth, alpha


def fit_hull(base: PlantParams, windows: Windows, free: Sequence[str], on_eval: EvalHook | None = None,
             start: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None) -> HullFit:
    """Fit the free hull figures (none: only the start states) to the recorded depth, from base's values."""
    free = tuple(free)
    n_free, n_win = len(free), windows.count
    scales = np.array([HULL_FIELDS[name][0] for name in free]
                      + [_STATE_SCALE[0]] * n_win + [_STATE_SCALE[1]] * n_win)
    z0, v0 = start if start is not None else start_states(windows)
    x0 = np.concatenate(([getattr(base, name) for name in free], z0, v0)) / scales
    # MINPACK's Levenberg-Marquardt takes no bounds: the plant sees the figures clipped to theirs instead
    # (a negative drag would make it blow up), so a figure pressed against a bound shows a wide interval.
    lower = np.concatenate(([HULL_FIELDS[n][1] for n in free], [-np.inf] * 2 * n_win))
    upper = np.concatenate(([HULL_FIELDS[n][2] for n in free], [np.inf] * 2 * n_win))
    count = [0]

    def unpack(x: NDArray[np.float64]) -> tuple[PlantParams, NDArray[np.float64], NDArray[np.float64]]:
        values = np.clip(x * scales, lower, upper)
        figures: dict[str, Any] = {name: float(v) for name, v in zip(free, values[:n_free], strict=True)}
        params = replace(base, **figures)
        return params, values[n_free:n_free + n_win], values[n_free + n_win:]

    owner = windows.owner()

    def depth_of(x: NDArray[np.float64]) -> NDArray[np.float64]:
        params, z0_x, v0_x = unpack(x)
        return simulate(params, windows, z0_x, v0_x)[0]

    def residuals(x: NDArray[np.float64]) -> NDArray[np.float64]:
        r = (depth_of(x) - windows.depth_m) / _RESIDUAL_UNIT_M
        count[0] += 1
        if on_eval is not None:
            on_eval(count[0], float(np.sqrt(np.mean(r * r))) * _RESIDUAL_UNIT_M)
        return r

    def jacobian(x: NDArray[np.float64]) -> csr_matrix:
        # Forward differences in n_free + 2 runs of the plant, not one per number: a window's residuals depend
        # on its own start state only, so every window's z0 (then v0) is nudged in the same run.
        # Sparse: the covariance's J^T J then costs samples x (free + 2), not samples x windows.
        at = depth_of(x)
        columns = []
        for j in range(n_free):
            step = _STEP * max(1.0, abs(x[j]))
            nudged = x.copy()
            nudged[j] += step
            columns.append((depth_of(nudged) - at) / step / _RESIDUAL_UNIT_M)
        for block in (n_free, n_free + n_win):
            nudged = x.copy()
            nudged[block:block + n_win] += _STEP
            columns.append((depth_of(nudged) - at) / _STEP / _RESIDUAL_UNIT_M)
        values = np.column_stack(columns) if columns else np.zeros((len(at), 0))
        col_index = np.column_stack([np.broadcast_to(np.arange(n_free), (len(at), n_free)),
                                     n_free + owner, n_free + n_win + owner])
        return csr_matrix((values.ravel(), col_index.ravel(), np.arange(0, values.size + 1, values.shape[1])),
                          shape=(len(at), len(x)))

    # MINPACK's QR runs on one core without BLAS threads: on a busy machine it is ten times faster than the
    # trust-region solvers' dense SVD or their LSMR products, whose threads fight the other work.
    result = least_squares(residuals, x0, jac=lambda x: jacobian(x).toarray(), method="lm",
                           x_scale=1.0, xtol=1e-9, ftol=1e-9, gtol=1e-9, max_nfev=100)
    params, z0_fit, v0_fit = unpack(result.x)
    final = jacobian(result.x)
    jtj = (final.T @ final).toarray()
    n, p = len(windows.depth_m), len(x0)
    dof = max(n - p, 1)
    sigma2 = 2.0 * result.cost / dof
    covariance = sigma2 * np.linalg.pinv(jtj)[:n_free, :n_free] * np.outer(scales[:n_free], scales[:n_free])
    predicted, _ = simulate(params, windows, z0_fit, v0_fit)
    return HullFit(params=params, free=free, covariance=covariance,
                   residual_rms_m=float(np.sqrt(sigma2)) * _RESIDUAL_UNIT_M, dof=dof, z0_m=z0_fit, v0_mps=v0_fit,
                   predicted_m=predicted, evaluations=count[0])
