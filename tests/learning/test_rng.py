"""The shared random stream's normal draws: the ziggurat (the hardware-fast preset's sensor noise) is a standard
normal in its moments, its tails and by Kolmogorov-Smirnov, and a seed fixes its sequence."""

from __future__ import annotations

import numpy as np
import pytest
from numba import njit
from numpy.typing import NDArray
from scipy import stats

from learning.rng import normal, normal_ziggurat, stream_from_seed

N_DRAWS = 2_000_000  # ~0.02 s compiled; enough for P(|x| > 4) = 6.3e-5 to show ~127 times


@njit(cache=True)
def _draws(seed: int, n: int, ziggurat: bool) -> NDArray[np.float64]:
    state = stream_from_seed(seed)
    out = np.empty(n)
    for i in range(n):
        out[i] = normal_ziggurat(state) if ziggurat else normal(state)
    return out


@pytest.fixture(scope="module")
def draws() -> NDArray[np.float64]:
    return _draws(11, N_DRAWS, True)


def test_ziggurat_moments_are_a_standard_normals(draws: NDArray[np.float64]) -> None:
    se = 1.0 / np.sqrt(N_DRAWS)  # of the mean; the others' are small multiples of it
    assert abs(draws.mean()) < 4.0 * se
    assert abs(draws.std() - 1.0) < 4.0 * se / np.sqrt(2.0)
    assert abs(stats.skew(draws)) < 4.0 * np.sqrt(6.0) * se
    assert abs(stats.kurtosis(draws)) < 4.0 * np.sqrt(24.0) * se


@pytest.mark.parametrize("beyond", [1.0, 2.0, 3.0, 3.5, 4.0])  # 3.44: the base layer's tail starts there
def test_ziggurat_tails_are_a_standard_normals(draws: NDArray[np.float64], beyond: float) -> None:
    expected = 2.0 * stats.norm.sf(beyond)
    count = int((np.abs(draws) > beyond).sum())
    assert abs(count - expected * N_DRAWS) < 4.0 * np.sqrt(expected * N_DRAWS)
    # Both sides, each half of it.
    upper = int((draws > beyond).sum())
    assert abs(upper - count / 2) < 4.0 * np.sqrt(count / 4) + 1


def test_ziggurat_passes_kolmogorov_smirnov(draws: NDArray[np.float64]) -> None:
    assert stats.kstest(draws, "norm").pvalue > 0.01
    # and in finer detail on the body, where its 128 layers meet
    assert stats.kstest(draws[np.abs(draws) < 1.0], stats.truncnorm(-1.0, 1.0).cdf).pvalue > 0.01


def test_a_seed_fixes_the_ziggurats_draws() -> None:
    a, b, c = _draws(3, 1000, True), _draws(3, 1000, True), _draws(4, 1000, True)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    # Its own sequence, not Box-Muller's from the same stream.
    assert not np.array_equal(a, _draws(3, 1000, False))
