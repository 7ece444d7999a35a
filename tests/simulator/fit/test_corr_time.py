"""The noise's correlation time interval (simulator/fit/residuals.py corr_time_interval): never "0 s +/- 0".

Issue 42's family benchmark (52 more draws per agent) found a draw whose noise was all but white (0.64 ms at 40 Hz):
its residuals' lag-1 autocorrelation and the whole of its interval lay below 0, read as 0 s with a zero half-width,
an identified figure its error exceeded infinitely many times."""

from __future__ import annotations

import math

import numpy as np

from simulator.fit.model import Z95
from simulator.fit.residuals import corr_time_interval

DT_S = 0.025  # 40 Hz


def test_an_interval_wholly_below_zero_correlation_still_covers_an_all_but_white_noise() -> None:
    value, half_width = corr_time_interval(-0.06, 0.02, 1.0, DT_S)
    assert value == 0.0 and half_width > 0.0
    assert abs(0.00064 - value) <= half_width  # the draw's truth, inside
    # the width is what a lag-1 test on this many samples can tell from white: phi = 1.96 se
    assert math.isclose(half_width, -DT_S / np.log(Z95 * 0.02), rel_tol=1e-9)


def test_a_resolved_correlation_keeps_the_interval_its_autocorrelation_gives() -> None:
    rho, se = math.exp(-DT_S / 0.4), 0.004  # the tank family's 0.4 s noise, well resolved
    value, half_width = corr_time_interval(rho, se, 1.0, DT_S)
    assert math.isclose(value, 0.4, rel_tol=1e-9)
    low, high = (-DT_S / math.log(rho + k * Z95 * se) for k in (-1, 1))
    assert math.isclose(half_width, max(value - low, high - value), rel_tol=1e-12)


def test_an_autocorrelation_reaching_one_is_not_identified() -> None:
    assert math.isinf(corr_time_interval(0.99, 0.01, 1.0, DT_S)[1])
