"""Compiled transition-count model: allocation, recording (dense or sparse slots), export as P and R."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit
from numpy.typing import NDArray

N_ACTIONS = 2
COUNT_MAX = 65535  # uint16 counts, as on the Teensy


class ModelArrays(NamedTuple):
    """A learner's whole model as its kernels take it, one argument (numba takes it as a named tuple): the
    per-state counts of this module and the shared model's type histograms (learning/shared.py). A part the
    learner does not use is empty (no states or no types)."""

    succ_idx: NDArray[np.uint16]  # [S, 2, slots] successor of each slot (dense: slot k is successor k)
    succ_cnt: NDArray[np.uint16]  # [S, 2, slots] count of each slot
    reward_sum: NDArray[np.float32]  # [S, 2] rewards summed over the pair's transitions
    codes: NDArray[np.uint8]  # [T, slots] offset code of each slot of a type
    type_counts: NDArray[np.uint16]  # [T, slots] count of each slot of a type
    totals: NDArray[np.uint16]  # [T] sum of a type's counts
    type_evictions: NDArray[np.uint16]  # [T] slots a type evicted (saturating)
    since_plan: NDArray[np.uint16]  # [T] transitions a type counted since the last plan (saturating; plan_due)


@njit(cache=True, error_model="numpy")
def allocate_model(
    n_states: int, sparse: bool, slots: int
) -> tuple[NDArray[np.uint16], NDArray[np.uint16], NDArray[np.float32]]:
    """Empty (successor index, count, reward sum) arrays; dense uses one slot per successor."""
    n_slots = slots if sparse else n_states
    succ_idx = np.zeros((n_states, N_ACTIONS, n_slots), dtype=np.uint16)
    if not sparse:
        for s in range(n_states):
            for a in range(N_ACTIONS):
                for k in range(n_slots):
                    succ_idx[s, a, k] = k
    succ_cnt = np.zeros((n_states, N_ACTIONS, n_slots), dtype=np.uint16)
    reward_sum = np.zeros((n_states, N_ACTIONS), dtype=np.float32)
    return succ_idx, succ_cnt, reward_sum


@njit(cache=True, error_model="numpy")
def _row_total(succ_cnt: NDArray[np.uint16], s: int, a: int) -> int:
    total = 0
    for k in range(succ_cnt.shape[2]):
        total += int(succ_cnt[s, a, k])
    return total


@njit(cache=True, error_model="numpy")
def record_transition(
    succ_idx: NDArray[np.uint16],
    succ_cnt: NDArray[np.uint16],
    reward_sum: NDArray[np.float32],
    state: int,
    action: int,
    reward: float,
    next_state: int,
    sparse: bool,
) -> bool:
    """Alg. 3: count (s, a, s') and add the reward to the (s, a) sum; True if a sparse slot was evicted."""
    n_slots = succ_cnt.shape[2]
    slot = next_state
    evicted = False
    if sparse:
        slot = -1
        free = -1
        for k in range(n_slots):
            if succ_cnt[state, action, k] > 0:
                if int(succ_idx[state, action, k]) == next_state:
                    slot = k
                    break
            elif free < 0:
                free = k
        if slot < 0:
            if free < 0:
                # All slots taken: forget the rarest successor, keeping the mean reward unchanged.
                free = 0
                for k in range(1, n_slots):
                    if succ_cnt[state, action, k] < succ_cnt[state, action, free]:
                        free = k
                total = _row_total(succ_cnt, state, action)
                kept = total - int(succ_cnt[state, action, free])
                reward_sum[state, action] *= kept / total
                succ_cnt[state, action, free] = 0
                evicted = True
            slot = free
            succ_idx[state, action, slot] = next_state
    if succ_cnt[state, action, slot] == COUNT_MAX:
        # Saturation: halve the row (rounding up keeps every seen successor), proportions survive.
        total = _row_total(succ_cnt, state, action)
        for k in range(n_slots):
            succ_cnt[state, action, k] = (int(succ_cnt[state, action, k]) + 1) // 2
        reward_sum[state, action] *= _row_total(succ_cnt, state, action) / total
    succ_cnt[state, action, slot] += 1
    reward_sum[state, action] += reward
    return evicted


@njit(cache=True, error_model="numpy")
def dense_counts(succ_idx: NDArray[np.uint16], succ_cnt: NDArray[np.uint16]) -> NDArray[np.uint16]:
    """Counts C[s, s', a] as the paper writes them, whatever the storage form."""
    n_states = succ_cnt.shape[0]
    counts = np.zeros((n_states, n_states, N_ACTIONS), dtype=np.uint16)
    for s in range(n_states):
        for a in range(N_ACTIONS):
            for k in range(succ_cnt.shape[2]):
                c = succ_cnt[s, a, k]
                if c > 0:
                    counts[s, int(succ_idx[s, a, k]), a] = c
    return counts


@njit(cache=True, error_model="numpy")
def export_model_kernel(
    succ_idx: NDArray[np.uint16], succ_cnt: NDArray[np.uint16], reward_sum: NDArray[np.float32]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """P[s, s', a] = C / sum_s' C and R[s, a] = mean reward; untried rows are all zero."""
    counts = dense_counts(succ_idx, succ_cnt)
    n_states = counts.shape[0]
    p = np.zeros((n_states, n_states, N_ACTIONS))
    r = np.zeros((n_states, N_ACTIONS))
    for s in range(n_states):
        for a in range(N_ACTIONS):
            total = 0.0
            for s2 in range(n_states):
                total += counts[s, s2, a]
            if total > 0:
                for s2 in range(n_states):
                    p[s, s2, a] = counts[s, s2, a] / total
                r[s, a] = reward_sum[s, a] / total
    return p, r
