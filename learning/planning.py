"""Compiled value iteration over the count model (Alg. 4, fixed), warm-started, with the policy."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.acting import TIED
from learning.rng import uniform
from learning.spec import KernelSpec

# P and R of every (s, a) row, compressed: row_start [rows + 1] into succ and prob (successor states and their
# probabilities), mean_reward [rows], known [rows] (backed up, else the untried value). One tuple, so that
# the kernels that compile rows and those that plan over them do not each spell its five arrays.
Rows = tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.float64], NDArray[np.float64], NDArray[np.bool_]]


@njit(cache=True, error_model="numpy")
def _compile_rows(
    succ_idx: NDArray[np.uint16],
    succ_cnt: NDArray[np.uint16],
    reward_sum: NDArray[np.float32],
    spec: KernelSpec,
) -> Rows:
    """P and R once per planning call as compressed rows: value iteration then touches only non-zeros."""
    n_states, n_actions, n_slots = succ_cnt.shape
    row_start = np.zeros(n_states * n_actions + 1, dtype=np.int64)
    nnz = 0
    for s in range(n_states):
        for a in range(n_actions):
            for k in range(n_slots):
                if succ_cnt[s, a, k] > 0:
                    nnz += 1
            row_start[s * n_actions + a + 1] = nnz
    succ = np.empty(nnz, dtype=np.int64)
    prob = np.empty(nnz)
    mean_reward = np.zeros(n_states * n_actions)
    known = np.zeros(n_states * n_actions, dtype=np.bool_)
    for s in range(n_states):
        for a in range(n_actions):
            row = s * n_actions + a
            total = 0
            for k in range(n_slots):
                total += int(succ_cnt[s, a, k])
            j = row_start[row]
            for k in range(n_slots):
                c = succ_cnt[s, a, k]
                if c > 0:
                    succ[j] = int(succ_idx[s, a, k])
                    prob[j] = c / total
                    j += 1
            if total > 0:
                mean_reward[row] = reward_sum[s, a] / total
            # The printed Alg. 4 knows no threshold: any tried row is backed up, a never-tried one is 0.
            known[row] = total > 0 if spec.alg4_printed else total >= spec.known_count
    return row_start, succ, prob, mean_reward, known


@njit(cache=True, error_model="numpy", inline="always")
def _action_value(
    row: int,
    rows: Rows,
    values: NDArray[np.float64],
    spec: KernelSpec,
) -> float:
    row_start, succ, prob, mean_reward, known = rows
    if not known[row]:
        return 0.0 if spec.alg4_printed else spec.untried_q_value
    expected = 0.0
    row_sum = 0.0
    for j in range(row_start[row], row_start[row + 1]):
        expected += prob[j] * values[succ[j]]
        row_sum += prob[j]
    backup = mean_reward[row] + spec.gamma * expected
    # Printed form: Q = (sum_s' P)(R + gamma P v), equal to the standard backup when the row sums to 1.
    return row_sum * backup if spec.alg4_printed else backup


@njit(cache=True, error_model="numpy")
def plan_kernel(
    succ_idx: NDArray[np.uint16],
    succ_cnt: NDArray[np.uint16],
    reward_sum: NDArray[np.float32],
    values: NDArray[np.float64],
    q: NDArray[np.float64],
    policy: NDArray[np.int8],
    spec: KernelSpec,
    rng_state: NDArray[np.uint64],
) -> int:
    """Value iteration over the per-state count model from the current values; returns sweeps."""
    return plan_rows(_compile_rows(succ_idx, succ_cnt, reward_sum, spec), values, q, policy, spec, rng_state)


@njit(cache=True, error_model="numpy")
def plan_rows(
    rows: Rows,
    values: NDArray[np.float64],
    q: NDArray[np.float64],
    policy: NDArray[np.int8],
    spec: KernelSpec,
    rng_state: NDArray[np.uint64],
) -> int:
    """Value iteration over compressed rows until max |change| < tolerance or max_sweeps (or the early stop of
    plan_stable_sweeps: no greedy action changed for that many sweeps and max |change| < plan_loose_tolerance);
    returns sweeps.

    Jacobi sweeps as Alg. 4 prints them, or in-place (Gauss-Seidel) sweeps, which reach the same fixed
    point in about half the sweeps. (Alg. 4's printed stopping test compares the signed change with the
    tolerance, which read literally stops after one sweep; the absolute change is meant.)

    Fills q and the greedy policy (argmax, or argmin under the errata switch). Ties are broken at random
    here, once per call (ties_per_step False), or marked TIED for select_action_kernel to draw at every
    step (ties_per_step True).
    """
    n_states, n_actions = q.shape
    terminal = n_states - 1
    values[terminal] = 0.0
    new_values = values.copy()
    # The early stop (LearnerConfig.plan_stable_sweeps): each sweep's greedy action per state, and for how
    # many sweeps in a row none changed. Off (0), none of this runs and the sweeps are the plain ones.
    early = spec.plan_stable_sweeps > 0
    greedy = np.full(n_states if early else 0, -1, dtype=np.int8)
    stable = 0
    sweeps = 0
    while sweeps < spec.max_sweeps:
        delta = 0.0
        changed = False
        for s in range(terminal):
            best = -np.inf
            arg = 0
            for a in range(n_actions):
                row = s * n_actions + a
                value = _action_value(row, rows, values, spec)
                if value > best:
                    arg = a
                best = max(best, value)
            if early and greedy[s] != arg:
                changed = True  # (the first sweep always: -1 is no action)
                greedy[s] = arg
            delta = max(delta, abs(best - values[s]))
            new_values[s] = best
            if spec.in_place_sweeps:
                values[s] = best
        if not spec.in_place_sweeps:
            values[:] = new_values
        sweeps += 1
        if delta < spec.vi_tolerance:
            break
        if early:
            stable = 0 if changed else stable + 1
            if stable >= spec.plan_stable_sweeps and delta < spec.plan_loose_tolerance:
                break
    sign = -1.0 if spec.policy_argmin else 1.0
    for s in range(n_states):
        for a in range(n_actions):
            q[s, a] = 0.0 if s == terminal else _action_value(s * n_actions + a, rows, values, spec)
        d = sign * (q[s, 1] - q[s, 0])
        if d > 0.0:
            policy[s] = 1
        elif d < 0.0:
            policy[s] = 0
        elif spec.random_ties and spec.ties_per_step:
            policy[s] = TIED
        else:
            policy[s] = 1 if (spec.random_ties and uniform(rng_state) < 0.5) else 0
    return sweeps
