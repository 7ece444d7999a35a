"""Least squares of the compiled plant over the windows: the hull's, the gear's and the port's figures shared, each
window's start its own."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.stats import t as student_t

from simulator.fit.kernel import gear_outputs, simulate_windows
from simulator.fit.windows import Windows
from simulator.parameters import PlantParams, kernel_params

# The figures the least squares may free, with the scale the optimiser sees them in (a typical size) and bounds.
# The hull's, then the gear train's backlash and the pressure port's lag, which show only in the depth.
HULL_FIELDS: dict[str, tuple[float, float, float]] = {
    "added_mass_kg": (0.1, 0.0, 2.0),
    "drag_kgpm": (1.0, 0.0, 50.0),
    "trim_error_fraction": (1e-3, -0.05, 0.05),
    # >= 0: a hull that gains volume with depth is not a hull (issue 42 saw a fit report one).
    "compressibility_m3pm": (1e-7, 0.0, 1e-4),
    "backlash_deg": (1.0, 0.0, 10.0),
    "pressure_lag_s": (0.1, 0.0, 2.0),
}
# Figures whose lower bound 0 is a physical one: the optimiser sees |x|, so a figure at 0 still has a slope to
# leave it by (a clipped one would sit on a flat floor), and its interval is cut at 0 when reported.
NON_NEGATIVE = frozenset(name for name, (_, low, _) in HULL_FIELDS.items() if low == 0.0)
_STATE_SCALE = (0.01, 0.01)  # z0 in cm, v0 in cm/s
_RESIDUAL_UNIT_M = 1e-3  # residuals in mm keep the cost near 1 for a good fit
_STEP = 1e-6  # finite-difference step, in the scaled units (each number's typical size)
_MAX_ITERATIONS = 60  # Levenberg-Marquardt iterations; a warm start (a refit) needs a handful, a cold one 10-30
_FTOL = 3e-7  # an accepted step that lowers the cost by less than this share ends the fit
Z95 = 1.959964  # two-sided 95 % normal quantile

EvalHook = Callable[[int, float], None]  # (evaluations so far, RMS residual in m)


@dataclass
class HullFit:
    """The fitted plant, its shared figures' covariance and the windows' fitted start states."""

    params: PlantParams
    free: tuple[str, ...]
    covariance: NDArray[np.float64]  # of the free figures, in their own units (residual variance x (J^T J)^-1)
    # The same, robust to coloured noise and misfit: the bias-reduced sandwich over windows (CR2), its quantile
    robust_covariance: NDArray[np.float64]
    robust_quantile: float
    residual_rms_m: float
    dof: int  # samples minus fitted numbers
    phi: float  # the AR(1) coefficient the residuals were prewhitened by
    cost: float  # the prewhitened residuals' sum of squares, mm^2 (what the fit minimised)
    z0_m: NDArray[np.float64]
    v0_mps: NDArray[np.float64]
    predicted_m: NDArray[np.float64]
    measured_m: NDArray[np.float64]
    predicted_motor_deg: NDArray[np.float64]
    evaluations: int

    def half_width(self, name: str, robust: bool = False) -> float:
        """Half-width of the 95 % interval of a free figure: from the Jacobian at the optimum, or (robust) the
        bias-reduced sandwich over windows (CR2) with Student's t over G - 1, which holds when the residuals are
        coloured or the model misses something that differs from window to window."""
        i = self.free.index(name)
        if robust:
            return float(self.robust_quantile * np.sqrt(max(self.robust_covariance[i, i], 0.0)))
        return float(Z95 * np.sqrt(max(self.covariance[i, i], 0.0)))

    @property
    def residuals_m(self) -> NDArray[np.float64]:
        return self.predicted_m - self.measured_m


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


def window_gear_outputs(params: PlantParams, windows: Windows) -> NDArray[np.float64]:
    """The gear's output angle at each window's start (closed gear train where the history is unknown)."""
    motor0 = windows.alpha_deg[windows.starts]
    if params.backlash_deg <= 0.0 or len(windows.start_rows) != windows.count:
        return motor0.copy()
    out = motor0.copy()
    gear_outputs(windows.history_deg, windows.history_reset, windows.start_rows, 0.5 * params.backlash_deg, out)
    return out


def simulate(params: PlantParams, windows: Windows, z0_m: NDArray[np.float64],
             v0_mps: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Sensed depth and counted (motor-side) gear angle the plant predicts at every sample, each window from
    its start state."""
    depth = np.empty_like(windows.depth_m)
    motor = np.empty_like(windows.depth_m)
    simulate_windows(kernel_params(params), windows.t_s, windows.cmd_deg, windows.alpha_deg[windows.starts],
                     window_gear_outputs(params, windows), windows.starts, windows.ends, z0_m, v0_mps, depth, motor)
    return depth, motor


@dataclass
class WindowJacobian:
    """The least squares' Jacobian in its structure: the shared figures' columns dense, and each sample's two
    columns of its own window's start depth and velocity (windows are contiguous runs of rows)."""

    shared: NDArray[np.float64]  # samples x free figures
    z0: NDArray[np.float64]  # d residual / d (own window's z0), per sample
    v0: NDArray[np.float64]

    def window_sums(self, a: NDArray[np.float64], starts: NDArray[np.int64]) -> NDArray[np.float64]:
        """Per window, the sums of a's rows (a is samples x k)."""
        return np.asarray(np.add.reduceat(a, starts, axis=0), dtype=np.float64)


def _normal_blocks(jac: WindowJacobian, r: NDArray[np.float64], starts: NDArray[np.int64]) -> tuple[
        NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """J^T J and J^T r in blocks: (H_tt p x p, H_ts W x p x 2, H_ss W x 2 x 2, g_t p, g_s W x 2)."""
    states = np.stack((jac.z0, jac.v0), axis=1)
    h_tt = jac.shared.T @ jac.shared
    h_ts = jac.window_sums(jac.shared[:, :, None] * states[:, None, :], starts)
    h_ss = jac.window_sums(states[:, :, None] * states[:, None, :], starts)
    g_t = jac.shared.T @ r
    g_s = jac.window_sums(states * r[:, None], starts)
    return h_tt, h_ts, h_ss, g_t, g_s


def _solve_blocks(h_tt: NDArray[np.float64], h_ts: NDArray[np.float64], h_ss: NDArray[np.float64],
                  g_t: NDArray[np.float64], g_s: NDArray[np.float64],
                  damping: float) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The damped Gauss-Newton step (Marquardt: the diagonal scaled by 1 + damping), each window's two start
    states eliminated first (Schur complement): p x p and W 2 x 2 solves instead of one of p + 2 W."""
    a = h_tt + damping * np.diag(np.diag(h_tt))
    d = h_ss.copy()
    d[:, 0, 0] *= 1.0 + damping
    d[:, 1, 1] *= 1.0 + damping
    d_inv = np.linalg.inv(d + 1e-12 * np.eye(2))
    b_dinv = np.einsum("wpi,wij->wpj", h_ts, d_inv)
    reduced = a - np.einsum("wpj,wqj->pq", b_dinv, h_ts)
    rhs = g_t - np.einsum("wpj,wj->p", b_dinv, g_s)
    step_t = np.linalg.lstsq(reduced, rhs, rcond=None)[0] if len(g_t) else np.zeros(0)
    step_s = np.einsum("wij,wj->wi", d_inv, g_s - np.einsum("wpi,p->wi", h_ts, step_t))
    return step_t, step_s


def robust_covariance(jac: WindowJacobian, residuals: NDArray[np.float64], starts: NDArray[np.int64],
                       ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(bread inverse, the bias-reduced cluster sandwich) of the shared figures, each window's start profiled out.

    Per window w the shared columns are projected off its two start-state columns (J_perp); the bread B is
    sum J_perp^T J_perp (its inverse is the classical covariance over sigma^2) and the meat sums the windows'
    scores outer themselves. The plain sandwich (scores g_w = J_perp^T r_w) is optimistic with ten windows: each
    window's residuals were fitted by the figures it pulls on, so its score is shrunk by its own leverage
    H_w = J_perp,w B^-1 J_perp,w^T. Bell and McCaffrey's CR2 undoes that: r_w is taken as (I - H_w)^-1/2 r_w,
    unbiased when the model is right, and the interval takes Student's t over the G - 1 windows (HullFit).
    With B_w = J_perp,w^T J_perp,w = L L^T (on its range) the adjusted score is L (I - L^T B^-1 L)^-1/2 L^+ g_w:
    a p x p eigenproblem per window, no sample-sized matrix. Windows are independent where the noise's
    correlation is much shorter than a window (10 s against at most 1 s); what the model misses stays in the
    scores, whatever its form.
    """
    h_tt, h_ts, h_ss, g_t, g_s = _normal_blocks(jac, residuals, starts)
    n_win = len(starts)
    d_inv = np.linalg.inv(h_ss + 1e-12 * np.eye(2))
    b_dinv = np.einsum("wpi,wij->wpj", h_ts, d_inv)
    bread = h_tt - np.einsum("wpj,wqj->pq", b_dinv, h_ts)
    own = (jac.window_sums(jac.shared[:, :, None] * jac.shared[:, None, :], starts)
           - np.einsum("wpj,wqj->wpq", b_dinv, h_ts))  # B_w
    scores = jac.window_sums(jac.shared * residuals[:, None], starts) - np.einsum("wpj,wj->wp", b_dinv, g_s)
    inv = np.asarray(np.linalg.pinv(bread), dtype=np.float64)
    adjusted = np.zeros_like(scores)
    for w in range(n_win):
        lam, vec = np.linalg.eigh(own[w])
        keep = lam > 1e-12 * max(float(lam.max(initial=0.0)), 1e-300)
        if not keep.any():
            continue  # the window pulls on no figure
        root = vec[:, keep] * np.sqrt(lam[keep])  # L
        k_lam, k_vec = np.linalg.eigh(np.eye(root.shape[1]) - root.T @ inv @ root)
        # A leverage of 1 (one window alone pins a direction) leaves no residual to judge it by: 1e-12 keeps it
        # finite and huge, which is what the data say of that direction.
        inv_sqrt = (k_vec / np.sqrt(np.maximum(k_lam, 1e-12))) @ k_vec.T
        adjusted[w] = root @ inv_sqrt @ ((vec[:, keep].T @ scores[w]) / np.sqrt(lam[keep]))
    spread = adjusted @ inv
    return inv, np.asarray(spread.T @ spread, dtype=np.float64)


def _whiten(a: NDArray[np.float64], first: NDArray[np.bool_], phi: float) -> NDArray[np.float64]:
    """AR(1) prewhitening within windows (rows): u_t = a_t - phi a_{t-1}, a window's first row scaled by
    sqrt(1 - phi^2) (Prais-Winsten), so least squares on u is generalised least squares under AR(1) noise."""
    if phi == 0.0:
        return a
    out = a.copy()
    out[1:] -= phi * a[:-1]
    out[first] = np.sqrt(1.0 - phi * phi) * a[first]
    return out


def fit_hull(base: PlantParams, windows: Windows, free: Sequence[str], on_eval: EvalHook | None = None,
             start: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None, phi: float = 0.0) -> HullFit:
    """Fit the free figures (none: only the start states) to the recorded depth, from base's values.

    phi: the noise's lag-1 autocorrelation at the sample rate; the residuals are prewhitened by it (GLS), which
    keeps the Jacobian's intervals right under coloured noise (ordinary least squares' are too narrow there).
    """
    free = tuple(free)
    first = np.zeros(len(windows.t_s), dtype=np.bool_)
    first[windows.starts] = True
    n_free, n_win = len(free), windows.count
    scales = np.array([HULL_FIELDS[name][0] for name in free]
                      + [_STATE_SCALE[0]] * n_win + [_STATE_SCALE[1]] * n_win)
    z0, v0 = start if start is not None else start_states(windows)
    x0 = np.concatenate(([getattr(base, name) for name in free], z0, v0)) / scales
    reflect = np.array([name in NON_NEGATIVE for name in free] + [False] * 2 * n_win)
    # The Levenberg-Marquardt below takes no bounds: the plant sees the figures clipped to theirs instead
    # (a negative drag would make it blow up), so a figure pressed against a bound shows a wide interval.
    lower = np.concatenate(([HULL_FIELDS[n][1] for n in free], [-np.inf] * 2 * n_win))
    upper = np.concatenate(([HULL_FIELDS[n][2] for n in free], [np.inf] * 2 * n_win))
    count = [0]

    def unpack(x: NDArray[np.float64]) -> tuple[PlantParams, NDArray[np.float64], NDArray[np.float64]]:
        values = x * scales
        values = np.clip(np.where(reflect, np.abs(values), values), lower, upper)
        figures: dict[str, Any] = {name: float(v) for name, v in zip(free, values[:n_free], strict=True)}
        params = replace(base, **figures)
        return params, values[n_free:n_free + n_win], values[n_free + n_win:]

    def depth_of(x: NDArray[np.float64]) -> NDArray[np.float64]:
        params, z0_x, v0_x = unpack(x)
        return simulate(params, windows, z0_x, v0_x)[0]

    def residuals(depth: NDArray[np.float64]) -> NDArray[np.float64]:
        r = (depth - windows.depth_m) / _RESIDUAL_UNIT_M
        count[0] += 1
        if on_eval is not None:
            on_eval(count[0], float(np.sqrt(np.mean(r * r))) * _RESIDUAL_UNIT_M)
        return _whiten(r, first, phi)

    def jacobian(x: NDArray[np.float64], at: NDArray[np.float64]) -> WindowJacobian:
        # Forward differences in n_free + 2 runs of the plant, not one per number: a window's residuals depend
        # on its own start state only, so every window's z0 (then v0) is nudged in the same run.
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
        values = _whiten(np.column_stack(columns), first, phi)
        return WindowJacobian(shared=values[:, :n_free], z0=values[:, n_free], v0=values[:, n_free + 1])

    # Levenberg-Marquardt on the structure: each window's start state is eliminated in closed form, so an
    # iteration costs samples x free figures, not samples x (free + 2 windows) as MINPACK's dense QR does (ten
    # minutes at 40 Hz: 126 columns, 20x the work).
    x = x0.copy()
    depth = depth_of(x)
    r = residuals(depth)
    cost = float(r @ r)
    damping = 1e-3
    for _ in range(_MAX_ITERATIONS):
        jac = jacobian(x, depth)
        blocks = _normal_blocks(jac, r, windows.starts)
        improved = False
        while damping < 1e10:
            step_t, step_s = _solve_blocks(*blocks, damping)
            trial = x.copy()
            trial[:n_free] -= step_t
            trial[n_free:n_free + n_win] -= step_s[:, 0]
            trial[n_free + n_win:] -= step_s[:, 1]
            trial_depth = depth_of(trial)
            trial_r = residuals(trial_depth)
            trial_cost = float(trial_r @ trial_r)
            if trial_cost < cost:
                improved = True
                break
            damping *= 4.0
        if not improved:
            break
        gain = (cost - trial_cost) / cost
        x, depth, r, cost = trial, trial_depth, trial_r, trial_cost
        damping = max(damping / 3.0, 1e-9)
        if gain < _FTOL:
            break
    final = jacobian(x, depth)
    params, z0_fit, v0_fit = unpack(x)
    n, p = len(windows.depth_m), len(x0)
    dof = max(n - p, 1)
    sigma2 = cost / dof
    # d(figure)/dx: the scale, and the sign where the optimiser saw |x|.
    chain = scales[:n_free] * np.where(reflect[:n_free] & (x[:n_free] < 0), -1.0, 1.0)
    inv_bread, sandwich = robust_covariance(final, r, windows.starts)
    covariance = sigma2 * inv_bread * np.outer(chain, chain)
    robust = sandwich * np.outer(chain, chain)
    quantile = float(student_t.ppf(0.975, max(n_win - 1, 1)))  # CR2's: the spread of G - 1 windows
    predicted, motor = simulate(params, windows, z0_fit, v0_fit)
    # The depth residual itself (not the prewhitened one the optimiser saw): the sensor noise's RMS and more.
    raw_rms_m = float(np.sqrt(np.sum((predicted - windows.depth_m) ** 2) / dof))
    return HullFit(params=params, free=free, covariance=covariance, robust_covariance=robust,
                   robust_quantile=quantile, residual_rms_m=raw_rms_m, dof=dof, phi=phi, cost=cost,
                   z0_m=z0_fit, v0_mps=v0_fit, predicted_m=predicted, measured_m=windows.depth_m,
                   predicted_motor_deg=motor, evaluations=count[0])
