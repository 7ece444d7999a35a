"""A counter-based random stream (SplitMix64) that numba kernels and Python share, one per trial."""

from __future__ import annotations

import math

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


# Marsaglia and Tsang's ziggurat for the standard normal (J. Stat. Softw. 5(8), 2000): 128 layers of equal area under
# the density, the base layer carrying the tail beyond _ZIG_R. A draw lands inside its layer's rectangle, and is
# returned with one multiplication, 98.8 % of the time; Box-Muller's log, square root and cosine cost ~4x more, and a
# study of the closed-form plant draws one normal per learner step (issue 43).
_ZIG_LAYERS = 128
_ZIG_R = 3.442619855899  # where the tail starts
_ZIG_AREA = 9.91256303526217e-3  # of each layer (the base layer's rectangle and tail together)
_ZIG_SCALE = 2147483648.0  # 2^31: the value is a signed 32-bit integer times the layer's width over 2^31
_S32 = np.uint64(32)
_LOW_32 = np.uint64(0xFFFFFFFF)
_LAYER_MASK = np.uint64(_ZIG_LAYERS - 1)


def _ziggurat_tables() -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.int64]]:
    """(w, f, k) of the 128 layers as Marsaglia and Tsang's zigset computes them: layer i's x-scale w (its right edge
    over 2^31), the density f at its right edge, and the |j| below which a signed 32-bit j lands inside the layer's
    rectangle (no density test needed). math's exp and log are the C library's, as the compiled kernels' are."""
    w = np.zeros(_ZIG_LAYERS)
    f = np.zeros(_ZIG_LAYERS)
    k = np.zeros(_ZIG_LAYERS, dtype=np.int64)
    edge = previous = _ZIG_R
    q = _ZIG_AREA / math.exp(-0.5 * edge * edge)
    k[0] = int(edge / q * _ZIG_SCALE)
    w[0] = q / _ZIG_SCALE
    w[-1] = edge / _ZIG_SCALE
    f[0] = 1.0
    f[-1] = math.exp(-0.5 * edge * edge)
    for i in range(_ZIG_LAYERS - 2, 0, -1):
        edge = math.sqrt(-2.0 * math.log(_ZIG_AREA / edge + math.exp(-0.5 * edge * edge)))
        k[i + 1] = int(edge / previous * _ZIG_SCALE)
        previous = edge
        f[i] = math.exp(-0.5 * edge * edge)
        w[i] = edge / _ZIG_SCALE
    return w, f, k


_ZIG_W, _ZIG_F, _ZIG_K = _ziggurat_tables()


@njit(cache=True, error_model="numpy", inline="always")
def normal_ziggurat(state: NDArray[np.uint64]) -> float:
    """A standard normal draw by the ziggurat: one 64-bit draw and no log or cosine 98.8 % of the time.

    A different sequence than normal() from the same stream (a preset chooses which, PlantParams.ziggurat_noise).
    The value's 32 signed bits and the layer's 7 bits are different bits of the draw, so the layer does not depend on
    the value (Doornik 2005: Marsaglia and Tsang's original took both from the same 32 bits)."""
    while True:
        bits = next_uint64(state)
        layer = int((bits >> _S32) & _LAYER_MASK)
        j = int(bits & _LOW_32) - 2147483648
        x = j * _ZIG_W[layer]
        if abs(j) < _ZIG_K[layer]:
            return x
        if layer == 0:
            # Beyond _ZIG_R: Marsaglia's (1964) exact tail.
            while True:
                xt = -np.log(1.0 - uniform(state)) / _ZIG_R
                yt = -np.log(1.0 - uniform(state))
                if yt + yt >= xt * xt:
                    return _ZIG_R + xt if j > 0 else -_ZIG_R - xt
        # In the wedge between the rectangle and the density: accept under the density, else draw again.
        if _ZIG_F[layer] + uniform(state) * (_ZIG_F[layer - 1] - _ZIG_F[layer]) < np.exp(-0.5 * x * x):
            return x
