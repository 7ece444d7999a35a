"""A counter-based random stream (SplitMix64) that numba kernels and Python share, one per trial."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

# SplitMix64 constants (Steele, Lea, Flood 2014). A single uint64 of state lets every trial of a
# parallel study carry its own reproducible stream without numba's per-thread global generator.
_GOLDEN_GAMMA = np.uint64(0x9E3779B97F4A7C15)
_MIX_1 = np.uint64(0xBF58476D1CE4E5B9)
_MIX_2 = np.uint64(0x94D049BB133111EB)
_S30 = np.uint64(30)
_S27 = np.uint64(27)
_S31 = np.uint64(31)
_S11 = np.uint64(11)
_TWO_POW_MINUS_53 = 1.0 / 9007199254740992.0


def new_stream(rng: np.random.Generator) -> NDArray[np.uint64]:
    """A fresh stream state drawn from a numpy Generator, so a seed fixes everything downstream."""
    return rng.integers(0, np.iinfo(np.uint64).max, size=1, dtype=np.uint64, endpoint=True)


@njit(cache=True, error_model="numpy")
def stream_from_seed(seed: int) -> NDArray[np.uint64]:
    """A stream state from an integer seed (used inside compiled trial loops)."""
    state = np.empty(1, dtype=np.uint64)
    state[0] = np.uint64(seed) * _MIX_2 + _GOLDEN_GAMMA
    return state


@njit(cache=True, error_model="numpy", inline="always")
def next_uint64(state: NDArray[np.uint64]) -> np.uint64:
    """Advance the stream and return 64 random bits."""
    state[0] = state[0] + _GOLDEN_GAMMA
    z = state[0]
    z = (z ^ (z >> _S30)) * _MIX_1
    z = (z ^ (z >> _S27)) * _MIX_2
    return z ^ (z >> _S31)


@njit(cache=True, error_model="numpy", inline="always")
def uniform(state: NDArray[np.uint64]) -> float:
    """A double uniform on [0, 1)."""
    return float(next_uint64(state) >> _S11) * _TWO_POW_MINUS_53


@njit(cache=True, error_model="numpy", inline="always")
def normal(state: NDArray[np.uint64]) -> float:
    """A standard normal draw (Box-Muller; the second variate is dropped to keep the state single)."""
    u1 = 1.0 - uniform(state)
    u2 = uniform(state)
    return np.sqrt(-2.0 * np.log(u1)) * np.cos(2.0 * np.pi * u2)
