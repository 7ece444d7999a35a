"""The fit's interval arithmetic: the bias-reduced sandwich over windows against the textbook's sample-sized
formula, and the depth-scale bound's half-width against the coverage it promises."""

from __future__ import annotations

import numpy as np

from simulator.fit.estimate import with_scale
from simulator.fit.model import Z95, WindowJacobian, robust_covariance


def _textbook_cr2(shared: np.ndarray, states: np.ndarray, r: np.ndarray, sizes: list[int]) -> np.ndarray:
    """CR2 written out: per window, the shared columns and the residuals within-projected off the window's own
    start-state columns, (M_w - H_w)^+1/2 applied to the residuals, n_w x n_w matrices throughout."""
    edges = np.cumsum([0, *sizes])
    perp = np.empty_like(shared)
    projectors = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        s = states[a:b]
        m = np.eye(b - a) - s @ np.linalg.pinv(s.T @ s) @ s.T
        projectors.append(m)
        perp[a:b] = m @ shared[a:b]
    bread_inv = np.linalg.inv(perp.T @ perp)
    meat = np.zeros((shared.shape[1], shared.shape[1]))
    for (a, b), m in zip(zip(edges[:-1], edges[1:], strict=True), projectors, strict=True):
        j = perp[a:b]
        lam, vec = np.linalg.eigh(m - j @ bread_inv @ j.T)
        keep = lam > 1e-9
        root_pinv = (vec[:, keep] / np.sqrt(lam[keep])) @ vec[:, keep].T
        score = j.T @ root_pinv @ r[a:b]
        meat += np.outer(score, score)
    return bread_inv @ meat @ bread_inv


def test_the_sandwich_is_bell_and_mccaffreys_cr2_with_each_windows_start_profiled_out() -> None:
    rng = np.random.default_rng(42)
    sizes = [30, 25, 40, 35, 30]
    n = sum(sizes)
    shared = rng.normal(size=(n, 3))
    t = np.concatenate([np.arange(k) / k for k in sizes])
    states = np.column_stack((np.ones(n), t))  # a window's start depth and velocity: a level and a slope
    r = rng.normal(size=n) * (1.0 + t)  # heteroscedastic: the sandwich's case
    starts = np.cumsum([0, *sizes[:-1]]).astype(np.int64)
    jacobian = WindowJacobian(shared=shared, z0=states[:, 0].copy(), v0=states[:, 1].copy())
    inv, cr2 = robust_covariance(jacobian, r, starts)
    expected = _textbook_cr2(shared, states, r, sizes)
    assert np.allclose(cr2, expected, rtol=1e-8, atol=0.0), (cr2, expected)
    # And it is not the plain sandwich: each window's leverage makes it wider.
    plain = np.zeros((3, 3))
    for a, b in zip(starts, [*starts[1:], n], strict=True):
        s = states[a:b]
        m = np.eye(b - a) - s @ np.linalg.pinv(s.T @ s) @ s.T
        score = (m @ shared[a:b]).T @ r[a:b]
        plain += np.outer(score, score)
    assert np.all(np.diag(cr2) > np.diag(inv @ plain @ inv))


def test_the_depth_scale_bound_is_covered_at_its_worst_and_reduces_to_each_term_alone() -> None:
    assert with_scale(0.3, 0.0) == 0.3  # no scale error: the statistical half-width
    assert with_scale(0.0, 0.2) == 0.2  # no statistical spread: the shift itself
    rng = np.random.default_rng(7)
    z = rng.normal(size=400_000)
    for half_width, shift in ((1.0, 0.3), (1.0, 1.0), (0.4, 2.0)):
        q = with_scale(half_width, shift)
        sigma = half_width / Z95
        # At the bound (the worst case) the interval holds 95 %; anywhere inside it, more.
        assert abs(np.mean(np.abs(sigma * z + shift) <= q) - 0.95) < 0.003
        assert np.mean(np.abs(sigma * z + 0.5 * shift) <= q) > 0.95
        # Wider than quadrature, which covered less when the two terms are alike; never wider than their sum.
        assert np.hypot(half_width, shift) <= q <= half_width + shift
