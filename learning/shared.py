"""The shared (relocatable) transition model: one histogram of grid offsets per state *type*.

Why: the plant's dynamics do not depend on depth (both presets; not true of a compressible hull), so what
happens after action a in velocity cell v with the actuator in bin b is the same at every depth cell. One
histogram per type (v, b, a) pools the experience of all ten depth cells: the model is learnt ten times
faster and in a tenth of the memory.

Model, for porting (the C twin keeps exactly this layout; `shared_memory_bytes` counts it):

- Grid: Z depth cells x V velocity cells x B actuator bins; state s = (b * Z + z) * V + v, the terminal
  state S - 1 = Z * V * B last (as in the paper's learner).
- Types: t = (b * V + v) * 2 + a, T = V * B * 2 of them.
- Per type, `slots` (12) slots of {uint8 offset code, uint16 count}, then uint16 total (sum of the
  counts) and uint16 evictions (saturating): 3 * slots + 4 bytes, 40 B with 12 slots.
- Offset code of a successor: ((dz + 2) * 17 + (dv + 8)) * 3 + (db + 1) for dz in -2..2, dv in -8..8,
  db in -1..1 (cells of the *unclipped* grid: a successor outside the region has cells beyond it);
  any other offset is FAR = 255, which is always terminal.
- Shifting: the successor of s = (b, z, v) under code (dz, dv, db) is (clip(b + db), z + dz, v + dv);
  z + dz outside 0..Z-1, or v + dv outside 0..V-1 (unless depth_only_terminal, which clips v), is the
  terminal state.
- Reward from the cell, no reward table: r(s') = -|centre of s' depth cell - z_d|
  - velocity_penalty * |centre of s' velocity cell| (the second term only when velocity_penalty > 0),
  the terminal reward (-10; -100 in the bins7 presets) for the terminal state.
- No Q table, no policy table: Q(s, a) = sum_k c_k / total * (r(s'_k) + gamma v(s'_k)) (+ count bonus)
  from V and the type's slots when acting or planning; a type with total < known_count has Q =
  untried_q_value (0: optimistic). Values: float32 per state, terminal included (always 0).
- Counts saturate as the per-state model's do: when a total would pass 65535 every count of the type is
  halved (rounding up) and the total recomputed. A successor that finds no free slot evicts the rarest
  one (its count leaves the total; the eviction counter counts it).
- With plan_growth > 0 (planning on growth, plan_due): per type a uint16 count of the transitions recorded since
  the last plan (saturating), zeroed by every plan. The firmware keeps it beside the model, as it does the early
  stop's greedy bits (firmware/src/shared.h shared_total_bytes), so shared_memory_bytes does not count it.
- Optional Dirichlet blend (dirichlet_weight w > 0): the per-state sparse model of learning/model.py as
  well (slots of {uint8 successor, uint16 count} per (s, a), no reward sums); P(s'|s, a) = (c_local(s')
  + w * P_shared(s')) / (n_local + w).

Python precomputes the shifted rows once per planning call (compressed rows, plan_rows); the firmware
may shift on the fly. Both give the same Q. Planning over these rows, and when to plan, is learning/shared_plan.py.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.model import COUNT_MAX, N_ACTIONS, ModelArrays, allocate_model
from learning.planning import Rows
from learning.spec import KernelSpec

DZ_MAX, DV_MAX, DB_MAX = 2, 8, 1  # offsets a code can hold; beyond them a successor is FAR (terminal)
_DV_SPAN, _DB_SPAN = 2 * DV_MAX + 1, 2 * DB_MAX + 1
FAR = 255
_FAR_DZ = 1 << 30  # a decoded FAR code's depth offset: off every grid
_TYPE_HEADER_BYTES = 4  # uint16 total + uint16 evictions
_SLOT_BYTES = 3  # uint8 offset code + uint16 count
_VALUE_BYTES = 4  # float32 per state
_LOCAL_SLOT_BYTES_SMALL, _LOCAL_SLOT_BYTES_LARGE = 3, 4  # uint8 / uint16 successor + uint16 count


def n_types(z_cells: int, zdot_cells: int, actuator_bins: int) -> int:
    """Number of (velocity cell, actuator bin, action) types."""
    del z_cells  # depth is what the model pools over
    return zdot_cells * actuator_bins * N_ACTIONS


def shared_memory_bytes(
    z_cells: int, zdot_cells: int, actuator_bins: int, slots: int, dirichlet: bool
) -> int:
    """Exact Teensy bytes: the type histograms, the values (float32, terminal included), local counts."""
    n_states = z_cells * zdot_cells * actuator_bins + 1
    total = n_types(z_cells, zdot_cells, actuator_bins) * (slots * _SLOT_BYTES + _TYPE_HEADER_BYTES)
    total += n_states * _VALUE_BYTES
    if dirichlet:
        per_slot = _LOCAL_SLOT_BYTES_SMALL if n_states <= 256 else _LOCAL_SLOT_BYTES_LARGE
        total += n_states * N_ACTIONS * slots * per_slot
    return total


@njit(cache=True, error_model="numpy")
def allocate_shared(
    n_type: int, slots: int
) -> tuple[NDArray[np.uint8], NDArray[np.uint16], NDArray[np.uint16], NDArray[np.uint16]]:
    """Empty (offset codes, counts, totals, evictions) of every type."""
    codes = np.zeros((n_type, slots), dtype=np.uint8)
    counts = np.zeros((n_type, slots), dtype=np.uint16)
    totals = np.zeros(n_type, dtype=np.uint16)
    evictions = np.zeros(n_type, dtype=np.uint16)
    return codes, counts, totals, evictions


@njit(cache=True, error_model="numpy")
def allocate_arrays(spec: KernelSpec) -> ModelArrays:
    """A learner's empty model: the per-state counts unless the shared model learns alone (no Dirichlet blend),
    the type histograms with the shared model; the part not used is empty."""
    n_states = spec.z_cells * spec.zdot_cells * spec.actuator_bins + 1
    shared = spec.shared_model
    local = (not shared) or spec.dirichlet_weight > 0.0
    succ_idx, succ_cnt, reward_sum = allocate_model(n_states if local else 0, spec.model_form == 1, spec.sparse_slots)
    n_type = spec.zdot_cells * spec.actuator_bins * N_ACTIONS if shared else 0
    codes, type_counts, totals, type_evictions = allocate_shared(n_type, spec.sparse_slots)
    since_plan = np.zeros(n_type, dtype=np.uint16)
    return ModelArrays(succ_idx, succ_cnt, reward_sum, codes, type_counts, totals, type_evictions, since_plan)


@njit(cache=True, error_model="numpy", inline="always")
def _raw(x: float, half_width: float, cells: int) -> int:
    """Cell index on the grid extended by one region width each side (clipped beyond that)."""
    i = int(np.floor((x + half_width) / (2.0 * half_width) * cells))
    return min(max(i, -cells), 2 * cells - 1)


@njit(cache=True, error_model="numpy", inline="always")
def raw_cell_kernel(
    depth_m: float, velocity_mps: float, target_depth_m: float, actuator_fraction: float, spec: KernelSpec
) -> int:
    """The unclipped cell of a measurement (inside the region or not), packed for record_shared."""
    rz = _raw(depth_m - target_depth_m, spec.z_tol_m, spec.z_cells) + spec.z_cells
    rv = _raw(velocity_mps, spec.zdot_tol_mps, spec.zdot_cells) + spec.zdot_cells
    ib = 0
    if spec.actuator_bins > 1:
        ib = int(np.floor((actuator_fraction + 1.0) / 2.0 * spec.actuator_bins))
        ib = min(max(ib, 0), spec.actuator_bins - 1)
    return (ib * 3 * spec.z_cells + rz) * 3 * spec.zdot_cells + rv


@njit(cache=True, error_model="numpy", inline="always")
def state_cell_code(state: int, spec: KernelSpec) -> int:
    """The raw cell code of a live state (what raw_cell_kernel gives for a point inside that cell)."""
    iv = state % spec.zdot_cells
    iz = (state // spec.zdot_cells) % spec.z_cells
    ib = state // (spec.zdot_cells * spec.z_cells)
    return (ib * 3 * spec.z_cells + iz + spec.z_cells) * 3 * spec.zdot_cells + iv + spec.zdot_cells


@njit(cache=True, error_model="numpy", inline="always")
def _offset_code(dz: int, dv: int, db: int) -> int:
    if abs(dz) > DZ_MAX or abs(dv) > DV_MAX or abs(db) > DB_MAX:
        return FAR
    return ((dz + DZ_MAX) * _DV_SPAN + (dv + DV_MAX)) * _DB_SPAN + (db + DB_MAX)


@njit(cache=True, error_model="numpy", inline="always")
def type_of(state: int, action: int, spec: KernelSpec) -> int:
    iv = state % spec.zdot_cells
    ib = state // (spec.zdot_cells * spec.z_cells)
    return (ib * spec.zdot_cells + iv) * N_ACTIONS + action


@njit(cache=True, error_model="numpy", inline="always")
def record_shared(model: ModelArrays, state: int, action: int, next_cell: int, spec: KernelSpec) -> bool:
    """Count the offset from state's cell to next_cell in the type's histogram; True if a slot was evicted."""
    codes, counts, totals, evictions = model.codes, model.type_counts, model.totals, model.type_evictions
    # Both cells decoded once each (a quotient and its remainder share one division): integer divisions by the
    # grid's sizes were most of a study's model update. The same offsets as state_cell_code and type_of give.
    v_cells, z_cells = spec.zdot_cells, spec.z_cells
    iv, rest = state % v_cells, state // v_cells
    iz, ib = rest % z_cells, rest // z_cells
    v3 = 3 * v_cells
    rv, rest = next_cell % v3, next_cell // v3
    rz, rb = rest % (3 * z_cells), rest // (3 * z_cells)
    code = _offset_code(rz - (iz + z_cells), rv - (iv + v_cells), rb - ib)
    t = (ib * v_cells + iv) * N_ACTIONS + action  # type_of(state, action)
    n_slots = counts.shape[1]
    slot = -1
    free = -1
    for k in range(n_slots):
        if counts[t, k] > 0:
            if int(codes[t, k]) == code:
                slot = k
                break
        elif free < 0:
            free = k
    evicted = False
    if slot < 0:
        if free < 0:
            free = 0
            for k in range(1, n_slots):
                if counts[t, k] < counts[t, free]:
                    free = k
            totals[t] = int(totals[t]) - int(counts[t, free])
            counts[t, free] = 0
            if evictions[t] < COUNT_MAX:
                evictions[t] += 1
            evicted = True
        slot = free
        codes[t, slot] = code
    if totals[t] == COUNT_MAX:
        total = 0
        for k in range(n_slots):
            counts[t, k] = (int(counts[t, k]) + 1) // 2
            total += int(counts[t, k])
        totals[t] = total
    counts[t, slot] += 1
    totals[t] += 1
    if model.since_plan[t] < COUNT_MAX:
        model.since_plan[t] += 1
    return evicted


@njit(cache=True, error_model="numpy", inline="always")
def _shift(state: int, code: int, spec: KernelSpec) -> int:
    """The successor state of `state` under an offset code; the terminal state if it leaves the region."""
    terminal = spec.z_cells * spec.zdot_cells * spec.actuator_bins
    if code == FAR:
        return terminal
    db = code % _DB_SPAN - DB_MAX
    dv = (code // _DB_SPAN) % _DV_SPAN - DV_MAX
    dz = code // (_DB_SPAN * _DV_SPAN) - DZ_MAX
    iv = state % spec.zdot_cells + dv
    iz = (state // spec.zdot_cells) % spec.z_cells + dz
    ib = min(max(state // (spec.zdot_cells * spec.z_cells) + db, 0), spec.actuator_bins - 1)
    if iz < 0 or iz >= spec.z_cells:
        return terminal
    if iv < 0 or iv >= spec.zdot_cells:
        if not spec.depth_only_terminal:
            return terminal
        iv = min(max(iv, 0), spec.zdot_cells - 1)
    return (ib * spec.z_cells + iz) * spec.zdot_cells + iv


@njit(cache=True, error_model="numpy", inline="always")
def cell_reward(state: int, spec: KernelSpec) -> float:
    """The reward of arriving in a state: minus its depth cell's centre distance, or the terminal reward."""
    if state == spec.z_cells * spec.zdot_cells * spec.actuator_bins:
        return spec.terminal_reward
    iz = (state // spec.zdot_cells) % spec.z_cells
    reward = -abs(-spec.z_tol_m + (iz + 0.5) * 2.0 * spec.z_tol_m / spec.z_cells)
    if spec.velocity_penalty > 0.0:
        iv = state % spec.zdot_cells
        reward -= spec.velocity_penalty * abs(-spec.zdot_tol_mps + (iv + 0.5) * 2.0 * spec.zdot_tol_mps
                                              / spec.zdot_cells)
    return reward


@njit(cache=True, error_model="numpy")
def shared_dense_counts(model: ModelArrays, spec: KernelSpec) -> NDArray[np.uint16]:
    """C[s, s', a] as the model holds it: each type's slots shifted to s (successors that leave the region
    on the terminal state), plus the local counts of the Dirichlet blend; saturating at COUNT_MAX. What
    an agent's COUNTS snapshot shows for a shared model (SPEC.md section 10; the firmware's learner_count)."""
    codes, counts, succ_idx, succ_cnt = model.codes, model.type_counts, model.succ_idx, model.succ_cnt
    n_states = spec.z_cells * spec.zdot_cells * spec.actuator_bins + 1
    out = np.zeros((n_states, n_states, N_ACTIONS), dtype=np.uint32)
    local = succ_cnt.shape[0] == n_states
    for s in range(n_states - 1):
        for a in range(N_ACTIONS):
            t = type_of(s, a, spec)
            for k in range(counts.shape[1]):
                if counts[t, k] > 0:
                    out[s, _shift(s, int(codes[t, k]), spec), a] += counts[t, k]
            if local:
                for k in range(succ_cnt.shape[2]):
                    if succ_cnt[s, a, k] > 0:
                        out[s, int(succ_idx[s, a, k]), a] += succ_cnt[s, a, k]
    return np.minimum(out, COUNT_MAX).astype(np.uint16)


@njit(cache=True, error_model="numpy")
def _decoded_slots(model: ModelArrays) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Each type's used slots in slot order: (how many [T], (slot, dz, dv, db) of each [T, slots, 4]); a FAR
    code gets a depth offset no grid has, so shifting by it is always terminal, as _shift makes it."""
    codes, counts = model.codes, model.type_counts
    n_type, n_slots = counts.shape
    used = np.zeros(n_type, dtype=np.int64)
    slots = np.zeros((n_type, n_slots, 4), dtype=np.int64)
    for t in range(n_type):
        for k in range(n_slots):
            if counts[t, k] > 0:
                code = int(codes[t, k])
                i = used[t]
                slots[t, i, 0] = k
                slots[t, i, 1] = _FAR_DZ if code == FAR else code // (_DB_SPAN * _DV_SPAN) - DZ_MAX
                slots[t, i, 2] = (code // _DB_SPAN) % _DV_SPAN - DV_MAX
                slots[t, i, 3] = code % _DB_SPAN - DB_MAX
                used[t] = i + 1
    return used, slots


@njit(cache=True, error_model="numpy")
def _type_offsets(
    used: NDArray[np.int64], slots: NDArray[np.int64], spec: KernelSpec
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Each type's used slots as (depth offset, state offset) from the state of a row of that type: its successor is
    the state plus the state offset while the depth cell plus the depth offset stays on the grid, else the terminal
    state (what _shift gives). A slot that is terminal from every depth cell (FAR, or off the velocity grid) gets a
    depth offset no grid has. The same for all of a type's depth cells: the rows then only add it."""
    z_cells, v_cells, bins = spec.z_cells, spec.zdot_cells, spec.actuator_bins
    n_type, n_slots = slots.shape[0], slots.shape[1]
    depth_offset = np.full((n_type, n_slots), _FAR_DZ, dtype=np.int64)
    state_offset = np.zeros((n_type, n_slots), dtype=np.int64)
    for t in range(n_type):
        iv0 = (t // N_ACTIONS) % v_cells
        ib0 = t // (N_ACTIONS * v_cells)
        for i in range(used[t]):
            iv = iv0 + slots[t, i, 2]
            if spec.depth_only_terminal:
                iv = min(max(iv, 0), v_cells - 1)
            if slots[t, i, 1] == _FAR_DZ or iv < 0 or iv >= v_cells:
                continue
            ib = min(max(ib0 + slots[t, i, 3], 0), bins - 1)
            depth_offset[t, i] = slots[t, i, 1]
            state_offset[t, i] = ((ib - ib0) * z_cells + slots[t, i, 1]) * v_cells + iv - iv0
    return depth_offset, state_offset


@njit(cache=True, error_model="numpy")
def compile_shared_rows(model: ModelArrays, spec: KernelSpec) -> Rows:
    """Every (s, a) row of P (shifted type histogram, blended with local counts) and its mean reward.

    The codes are decoded and their shifts worked out once per type (_type_offsets), the cell rewards once per
    state (both what _shift and cell_reward give), and the arrays sized to the rows' entries: so the rows are those
    the plain loops over slots give, bit for bit, at ~5x less CPU (issue 29), and 1.6x less again (issue 43).
    """
    counts, totals = model.type_counts, model.totals
    succ_idx, succ_cnt = model.succ_idx, model.succ_cnt
    z_cells, v_cells, bins = spec.z_cells, spec.zdot_cells, spec.actuator_bins
    n_states = z_cells * v_cells * bins + 1
    terminal = n_states - 1
    blend = spec.dirichlet_weight > 0.0 and succ_cnt.shape[0] == n_states
    local_slots = succ_cnt.shape[2] if blend else 0
    n_rows = n_states * N_ACTIONS
    used, slots = _decoded_slots(model)
    depth_offset, state_offset = _type_offsets(used, slots, spec)
    row_start = np.zeros(n_rows + 1, dtype=np.int64)
    # Each type's slots appear in the rows of its z_cells depth cells; the local counts at most once per slot.
    capacity = z_cells * used.sum() + (terminal * N_ACTIONS * local_slots)
    succ = np.empty(capacity, dtype=np.int64)
    prob = np.empty(capacity)
    mean_reward = np.zeros(n_rows)
    known = np.zeros(n_rows, dtype=np.bool_)
    reward_of = np.empty(n_states)
    for s in range(n_states):
        reward_of[s] = cell_reward(s, spec)
    j = 0
    w = spec.dirichlet_weight
    for s in range(terminal):
        iv0 = s % v_cells
        iz0 = (s // v_cells) % z_cells
        ib0 = s // (v_cells * z_cells)
        for a in range(N_ACTIONS):
            row = s * N_ACTIONS + a
            t = (ib0 * v_cells + iv0) * N_ACTIONS + a  # type_of(s, a)
            shared_total = float(totals[t])
            local_total = 0.0
            for k in range(local_slots):
                local_total += float(succ_cnt[s, a, k])
            # Weights of the two parts: the Dirichlet posterior mean, or whichever part has data.
            if local_total > 0.0 and shared_total > 0.0:
                w_local, w_shared = 1.0 / (local_total + w), w / (local_total + w) / shared_total
            elif local_total > 0.0:
                w_local, w_shared = 1.0 / local_total, 0.0
            else:
                w_local, w_shared = 0.0, (1.0 / shared_total if shared_total > 0.0 else 0.0)
            r = 0.0
            if w_shared > 0.0:
                for i in range(used[t]):
                    # _shift(s, code): off the grid in depth (or velocity, unless clipped) is terminal.
                    iz = iz0 + depth_offset[t, i]
                    nxt = s + state_offset[t, i] if 0 <= iz < z_cells else terminal
                    succ[j] = nxt
                    prob[j] = counts[t, slots[t, i, 0]] * w_shared
                    r += prob[j] * reward_of[nxt]
                    j += 1
            for k in range(local_slots):
                c = succ_cnt[s, a, k]
                if c > 0:
                    nxt = int(succ_idx[s, a, k])
                    succ[j] = nxt
                    prob[j] = c * w_local
                    r += prob[j] * reward_of[nxt]
                    j += 1
            n = shared_total + local_total
            known[row] = n >= spec.known_count
            if spec.count_bonus > 0.0 and n > 0.0:
                r += spec.count_bonus / np.sqrt(n)
            mean_reward[row] = r
            row_start[row + 1] = j
    row_start[terminal * N_ACTIONS + 1:] = j
    return row_start, succ[:j], prob[:j], mean_reward, known
