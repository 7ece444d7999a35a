"""Compiled value iteration over the count model (Alg. 4, fixed), warm-started, with the policy."""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.rng import uniform


@njit(cache=True)
def _action_values(
    succ_idx: NDArray[np.uint16],
    succ_cnt: NDArray[np.uint16],
    totals: NDArray[np.int64],
    mean_reward: NDArray[np.float64],
    values: NDArray[np.float64],
    s: int,
    a: int,
    spec: tuple,
) -> float:
    total = totals[s, a]
    if spec.alg4_printed:
        # Printed form: Q = (sum_s' P)(R + gamma P v); a never-tried row sums to 0, so Q = 0.
        if total == 0:
            return 0.0
    elif total < spec.known_count:
        return spec.untried_q_value
    expected = 0.0
    row_sum = 0.0
    for k in range(succ_cnt.shape[2]):
        c = succ_cnt[s, a, k]
        if c > 0:
            p = c / total
            expected += p * values[int(succ_idx[s, a, k])]
            row_sum += p
    backup = mean_reward[s, a] + spec.gamma * expected
    if spec.alg4_printed:
        return row_sum * backup
    return backup


@njit(cache=True)
def plan_kernel(
    succ_idx: NDArray[np.uint16],
    succ_cnt: NDArray[np.uint16],
    reward_sum: NDArray[np.float32],
    values: NDArray[np.float64],
    q: NDArray[np.float64],
    policy: NDArray[np.int8],
    spec: tuple,
    rng_state: NDArray[np.uint64],
) -> int:
    """Jacobi value iteration from the current values until max |change| < tolerance; returns sweeps.

    Fills q and the greedy policy (argmax, or argmin under the errata switch), ties broken at random.
    """
    n_states, n_actions = q.shape
    terminal = n_states - 1
    totals = np.zeros((n_states, n_actions), dtype=np.int64)
    mean_reward = np.zeros((n_states, n_actions))
    for s in range(n_states):
        for a in range(n_actions):
            t = 0
            for k in range(succ_cnt.shape[2]):
                t += int(succ_cnt[s, a, k])
            totals[s, a] = t
            if t > 0:
                mean_reward[s, a] = reward_sum[s, a] / t
    values[terminal] = 0.0
    new_values = values.copy()
    sweeps = 0
    while sweeps < spec.max_sweeps:
        delta = 0.0
        for s in range(terminal):
            best = _action_values(succ_idx, succ_cnt, totals, mean_reward, values, s, 0, spec)
            for a in range(1, n_actions):
                best = max(best, _action_values(succ_idx, succ_cnt, totals, mean_reward, values, s, a, spec))
            delta = max(delta, abs(best - values[s]))
            new_values[s] = best
        values[:] = new_values
        sweeps += 1
        if delta < spec.vi_tolerance:
            break
    for s in range(n_states):
        for a in range(n_actions):
            q[s, a] = 0.0 if s == terminal else _action_values(
                succ_idx, succ_cnt, totals, mean_reward, values, s, a, spec
            )
        sign = -1.0 if spec.policy_argmin else 1.0
        d = sign * (q[s, 1] - q[s, 0])
        if d > 0.0:
            policy[s] = 1
        elif d < 0.0:
            policy[s] = 0
        else:
            policy[s] = 1 if (spec.random_ties and uniform(rng_state) < 0.5) else 0
    return sweeps
