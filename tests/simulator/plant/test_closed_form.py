"""diving-agent.md s. 2's rule for a faster integrator (issue 43): the closed-form step's depth stays within 0.1 mm
of the 5 ms sub-steps' over a 300 s episode under the same commands, on every plant the simulator offers."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from numba import njit
from numpy.typing import NDArray

from learning.spec import KernelSpec
from simulator.parameters import PlantParams, kernel_params, neutral_alpha_deg, preset, with_overrides
from simulator.plant.kernel import PLANT_SIZE, SENSED_Z, ZDOT, Z, plant_place, plant_step
from simulator.study.kernel import FAST_MATH_FLAGS, compiled_again

RULE_M = 1e-4  # diving-agent.md s. 2: a sixth of the sensor's noise
EPISODE_S = 300.0

# The presets, each imperfection of docs/robust-plant.md at the tank family's far end (docs/families/tank.toml), and
# the hull's extremes; a compressible hull (no preset uses one) keeps the sub-steps, so it is exact.
PLANTS: dict[str, tuple[str, dict[str, float]]] = {
    "paper": ("paper", {}),
    "hardware": ("hardware", {}),
    "backlash 2 deg, dead band 0.5 deg": ("hardware", {"backlash_deg": 2.0, "dead_band_deg": 0.5}),
    "port lag 0.2 s": ("hardware", {"pressure_lag_s": 0.2}),
    "control jitter 5 ms": ("hardware", {"control_jitter_s": 0.005}),
    "heavy, draggy, tired stepper": ("hardware", {"drag_kgpm": 1.7, "added_mass_kg": 0.15, "alpha_rate_dps": 26.4}),
    "light, slick, 1 % trim": ("hardware", {"drag_kgpm": 0.7, "added_mass_kg": 0.06, "trim_error_fraction": 0.01}),
    "compressible hull": ("hardware", {"compressibility_m3pm": 2e-7}),
}


@njit(cache=True)
def _commands(state: NDArray[np.float64], spec: KernelSpec, centre_deg: float, step_deg: float,
              periods_s: NDArray[np.float64], noise: NDArray[np.float64]) -> NDArray[np.float64]:
    """A chattering two-action policy (the learner's kind of command) run on the plant: the commands it gave."""
    cmds = np.empty(periods_s.shape[0])
    cmd = centre_deg
    for k in range(periods_s.shape[0]):
        surface = state[ZDOT] + 0.3 * (state[Z] - 0.4) + noise[k]
        cmd = min(max(cmd + (step_deg if surface > 0.0 else -step_deg), centre_deg - 19.5), centre_deg + 19.5)
        cmds[k] = cmd
        plant_step(state, cmd, periods_s[k], spec)
    return cmds


@njit(cache=True)
def _replay(state: NDArray[np.float64], spec: KernelSpec, cmds: NDArray[np.float64],
            periods_s: NDArray[np.float64]) -> NDArray[np.float64]:
    """Depth and sensed depth after each period under the given commands."""
    out = np.empty((cmds.shape[0], 2))
    for k in range(cmds.shape[0]):
        plant_step(state, cmds[k], periods_s[k], spec)
        out[k, 0] = state[Z]
        out[k, 1] = state[SENSED_Z]
    return out


# The closed form in the fast arithmetic the hardware-fast preset's study runs it in (PlantParams.fast_arithmetic).
_replay_fast = compiled_again(_replay, "_replay_fast", FAST_MATH_FLAGS)


def _episode(params: PlantParams, period_s: float, seed: int,
             fast_arithmetic: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(reference, closed form) depth and sensed depth of one 300 s episode from a random start and neutral error;
    the reference in exact arithmetic, the closed form in fast arithmetic if asked."""
    rng = np.random.default_rng(seed)
    n = round(EPISODE_S / period_s)
    periods = period_s + params.control_jitter_s * (2.0 * rng.uniform(size=n) - 1.0)
    centre = neutral_alpha_deg(params) + rng.uniform(-3.0, 3.0)
    start = np.zeros(PLANT_SIZE)
    plant_place(start, 0.4 + rng.uniform(-0.09, 0.09), 0.0, centre)
    cmds = _commands(start.copy(), kernel_params(params), centre, params.action_step_deg, periods,
                     rng.normal(0.0, 0.002, n))
    fast = dataclasses.replace(params, closed_form_step=True)
    closed_form = _replay_fast if fast_arithmetic else _replay
    return (_replay(start.copy(), kernel_params(params), cmds, periods),
            closed_form(start.copy(), kernel_params(fast), cmds, periods))


@pytest.mark.parametrize("fast_arithmetic", [False, True], ids=["exact", "fast arithmetic"])
@pytest.mark.parametrize("name", list(PLANTS))
def test_closed_form_depth_stays_within_a_tenth_of_a_millimetre(name: str, fast_arithmetic: bool) -> None:
    base, overrides = PLANTS[name]
    params = with_overrides(preset(base), overrides)
    for period_s in (params.control_period_s, params.recovery_period_s):  # the learner's and the controller's
        for seed in range(2):
            reference, fast = _episode(params, period_s, seed, fast_arithmetic)
            assert np.ptp(reference[:, 0]) > 0.01  # the commands moved the agent
            assert np.abs(fast[:, 0] - reference[:, 0]).max() < RULE_M
            # The sensed depth (the port's lag) as well: what the learner reads.
            assert np.abs(fast[:, 1] - reference[:, 1]).max() < RULE_M


def test_near_the_surface_the_sub_steps_run() -> None:
    """The closed form knows no free surface: from the surface, where the agent sits at the start, the same bits."""
    params = preset("hardware")
    fast = dataclasses.replace(params, closed_form_step=True)
    for spec_params in (params, fast):
        state = np.zeros(PLANT_SIZE)
        plant_place(state, 0.0, 0.0, 80.0)  # more volume than neutral: it floats at the surface
        out = _replay(state, kernel_params(spec_params), np.full(50, 80.0), np.full(50, 0.1))
        if spec_params is params:
            reference = out
    assert np.array_equal(out, reference) and (out[:, 0] == 0.0).all()
