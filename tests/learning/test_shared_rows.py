"""The shared model's planning rows, bit for bit what the plain loop over slots gives (the 693fc12 planner)."""

from __future__ import annotations

import numpy as np
import pytest

from learning import Learner, LearnerConfig, learner_preset
from learning.config import kernel_spec, n_states
from learning.model import ModelArrays, record_transition
from learning.shared import FAR, allocate_arrays, cell_reward, compile_shared_rows, record_shared, type_of
from simulator.parameters import preset
from tests.simulator.python_trial import python_loop_trial

# Every branch of the row builder: plain, 20 depth cells x 7 bins, 13 bins, velocity clipped instead of
# terminal, the Dirichlet blend, the count bonus, R-MAX's known threshold.
CONFIGS = {
    "shared": learner_preset("shared"),
    "hardware": learner_preset("shared-z20-bins7-diff8-term100-vpen1"),
    "bins13": learner_preset("shared-bins13-diff4"),
    "depth-only": learner_preset("shared", depth_only_terminal=True, velocity_penalty=0.5),
    "dirichlet": learner_preset("shared-dirichlet"),
    "bonus": learner_preset("shared-bonus", known_count=3),
}


def shifted(state: int, code: int, config: LearnerConfig) -> int:
    """The successor of state under an offset code, as learning/shared.py's docstring specifies it."""
    terminal = n_states(config) - 1
    if code == FAR:
        return terminal
    dz, dv, db = code // 51 - 2, (code // 3) % 17 - 8, code % 3 - 1
    iv, iz = state % config.zdot_cells + dv, (state // config.zdot_cells) % config.z_cells + dz
    ib = min(max(state // (config.zdot_cells * config.z_cells) + db, 0), config.actuator_bins - 1)
    if not 0 <= iz < config.z_cells:
        return terminal
    if not 0 <= iv < config.zdot_cells:
        if not config.depth_only_terminal:
            return terminal
        iv = min(max(iv, 0), config.zdot_cells - 1)
    return (ib * config.z_cells + iz) * config.zdot_cells + iv


def reference_rows(model: ModelArrays, config: LearnerConfig) -> tuple[np.ndarray, ...]:
    """The rows as the planner built them before it decoded codes once per type: every (s, a), every slot
    shifted and rewarded on its own, in plain Python (IEEE double arithmetic, the same operations in the
    same order)."""
    spec = kernel_spec(config)
    states = n_states(config)
    blend = config.dirichlet_weight > 0.0 and model.succ_cnt.shape[0] == states
    w = config.dirichlet_weight
    row_start, succ, prob, mean_reward, known = [0], [], [], [], []
    for s in range(states):
        for a in range(2):
            if s == states - 1:
                row_start.append(len(succ))
                mean_reward.append(0.0)
                known.append(False)
                continue
            t = int(type_of(s, a, spec))
            shared_total = float(model.totals[t])
            local_total = 0.0
            for c in model.succ_cnt[s, a] if blend else ():
                local_total += float(c)
            if local_total > 0.0 and shared_total > 0.0:
                w_local, w_shared = 1.0 / (local_total + w), w / (local_total + w) / shared_total
            elif local_total > 0.0:
                w_local, w_shared = 1.0 / local_total, 0.0
            else:
                w_local, w_shared = 0.0, (1.0 / shared_total if shared_total > 0.0 else 0.0)
            r = 0.0
            parts = [(shifted(s, int(code), config), int(c), w_shared)
                     for code, c in zip(model.codes[t], model.type_counts[t], strict=True) if c > 0 and w_shared > 0]
            if blend:
                parts += [(int(nxt), int(c), w_local)
                          for nxt, c in zip(model.succ_idx[s, a], model.succ_cnt[s, a], strict=True) if c > 0]
            for nxt, c, weight in parts:
                succ.append(nxt)
                prob.append(c * weight)
                r += prob[-1] * float(cell_reward(nxt, spec))
            n = shared_total + local_total
            known.append(n >= config.known_count)
            if config.count_bonus > 0.0 and n > 0.0:
                r += config.count_bonus / np.sqrt(n)
            mean_reward.append(r)
            row_start.append(len(succ))
    return (np.array(row_start), np.array(succ, dtype=np.int64), np.array(prob), np.array(mean_reward),
            np.array(known))


def assert_bit_identical(model: ModelArrays, config: LearnerConfig) -> None:
    rows = compile_shared_rows(model, kernel_spec(config))
    for got, want, name in zip(rows, reference_rows(model, config), ("row_start", "succ", "prob", "mean_reward",
                                                                      "known"), strict=True):
        assert got.dtype == want.dtype and got.shape == want.shape, name
        assert got.tobytes() == want.tobytes(), name  # the bits, not a tolerance


def _fill_at_random(model: ModelArrays, config: LearnerConfig, rng: np.random.Generator, steps: int) -> None:
    """Random transitions: mostly a few cells away (the offsets a code holds), some far beyond (FAR)."""
    spec = kernel_spec(config)
    z3, v3 = 3 * config.z_cells, 3 * config.zdot_cells
    live = n_states(config) - 1
    for _ in range(steps):
        s, a = int(rng.integers(live)), int(rng.integers(2))
        iv, iz = s % config.zdot_cells, (s // config.zdot_cells) % config.z_cells
        ib = s // (config.zdot_cells * config.z_cells)
        if rng.random() < 0.1:
            rz, rv = int(rng.integers(z3)), int(rng.integers(v3))
        else:
            rz = min(max(iz + config.z_cells + int(rng.integers(-2, 3)), 0), z3 - 1)
            rv = min(max(iv + config.zdot_cells + int(rng.integers(-3, 4)), 0), v3 - 1)
        nb = min(max(ib + int(rng.integers(-1, 2)), 0), config.actuator_bins - 1)
        record_shared(model, s, a, (nb * z3 + rz) * v3 + rv, spec)
        if config.dirichlet_weight > 0.0 and rng.random() < 0.3:
            record_transition(model.succ_idx, model.succ_cnt, model.reward_sum, s, a, -0.1,
                              int(rng.integers(live + 1)), True)


@pytest.mark.parametrize("name", sorted(CONFIGS))
def test_rows_of_random_models_are_bit_identical_to_the_plain_loop(name: str) -> None:
    config = CONFIGS[name]
    model = allocate_arrays(kernel_spec(config))
    assert_bit_identical(model, config)  # empty: every row untried
    rng = np.random.default_rng(29)
    for steps in (3, 40, 2000):  # a few types, then most, then slots full and evicting
        _fill_at_random(model, config, rng, steps)
        assert_bit_identical(model, config)


def test_rows_of_a_real_hardware_trial_are_bit_identical_episode_by_episode() -> None:
    # The hardware learner on the hardware preset (the study's seeding of trial 0 of seed 3), each episode cut at
    # 60 s: after every episode the rows the planner sweeps are the old ones, so the values, policy and the whole
    # trial are.
    config = CONFIGS["hardware"]
    totals: list[int] = []

    def check(learner: Learner) -> None:
        assert_bit_identical(learner.arrays.model, config)
        totals.append(int(learner.arrays.model.totals.sum()))

    python_loop_trial(preset("hardware"), config, seed=3, trial=0, episodes=4, max_episode_s=60.0, before_end=check)
    assert len(totals) == 4 and totals[-1] > 100  # every episode checked, and it learned something to build rows from
