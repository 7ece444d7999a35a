"""Planning over the shared model (the twin of firmware/src/shared_plan.c): its Q from the live model, value iteration
over its compiled rows, and whether an episode's end plans at all (LearnerConfig.plan_growth)."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.model import N_ACTIONS, ModelArrays
from learning.planning import _action_value, plan_rows
from learning.shared import compile_shared_rows
from learning.spec import KernelSpec


@njit(cache=True, error_model="numpy")
def shared_q_kernel(model: ModelArrays, values: NDArray[np.float64], spec: KernelSpec) -> NDArray[np.float64]:
    """Q[s, a] from the live model and the current values (no planning): what a shared model's Q_VALUES
    snapshot shows, as the firmware computes it (it keeps no Q table)."""
    rows = compile_shared_rows(model, spec)
    n_states = values.shape[0]
    q = np.zeros((n_states, N_ACTIONS))
    for s in range(n_states - 1):
        for a in range(N_ACTIONS):
            q[s, a] = _action_value(s * N_ACTIONS + a, rows, values, spec)
    return q


@njit(cache=True, error_model="numpy")
def plan_shared_kernel(
    model: ModelArrays,
    values: NDArray[np.float64],
    q: NDArray[np.float64],
    policy: NDArray[np.int8],
    spec: KernelSpec,
    rng_state: NDArray[np.uint64],
) -> int:
    """Value iteration over the shared model (see plan_rows); returns sweeps. Every type's count since the last
    plan starts again from 0 (plan_due)."""
    model.since_plan[:] = 0
    rows = compile_shared_rows(model, spec)
    return plan_rows(rows, values, q, policy, spec, rng_state)


@njit(cache=True, error_model="numpy")
def plan_due(model: ModelArrays, spec: KernelSpec) -> bool:
    """Whether an episode's end plans (LearnerConfig.plan_growth): always with plan_growth 0; else once some type
    has counted, since the last plan, at least plan_growth times what it had then (its total less those, at least
    1: a type seen for the first time always plans, and so does one whose counts were halved or evicted below
    what it counted since). In double precision, as the firmware compares (shared_plan_due)."""
    if spec.plan_growth <= 0.0:
        return True
    totals, since = model.totals, model.since_plan
    for t in range(totals.shape[0]):
        new = int(since[t])
        if new > 0 and new >= spec.plan_growth * max(int(totals[t]) - new, 1):
            return True
    return False
