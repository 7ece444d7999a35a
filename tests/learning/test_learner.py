"""The learner against an independent solver, its errata switches, its model forms and memory."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from learning import Learner, LearnerConfig, ModelForm, n_states, state_index, terminal_state
from learning.errors import LearnerConfigError, LearningError

SMALL = LearnerConfig(z_cells=4, zdot_cells=3)  # 13 states keeps the independent solver tiny


def _feed_random_model(learner: Learner, rng: np.random.Generator, n: int, every_pair: bool = True) -> None:
    s_count = n_states(learner.config)
    terminal = s_count - 1
    succ = {(s, a): rng.choice(s_count, size=3, replace=False) for s in range(terminal) for a in (0, 1)}
    pairs = [(s, a) for s in range(terminal) for a in (0, 1)]
    for i in range(n):
        s, a = pairs[i % len(pairs)] if every_pair else pairs[rng.integers(len(pairs) // 2)]
        s2 = int(rng.choice(succ[(s, a)], p=[0.6, 0.3, 0.1]))
        reward = -10.0 if s2 == terminal else -float(rng.random())
        learner.observe(s, a, reward, s2)


def _policy_iteration(p: np.ndarray, r: np.ndarray, gamma: float) -> tuple[np.ndarray, np.ndarray]:
    """Howard's policy iteration by linear solves, terminal (last state) absorbing with value 0."""
    s_count = r.shape[0]
    live = s_count - 1
    policy = np.zeros(live, dtype=int)
    while True:
        p_pi = np.array([p[s, :live, policy[s]] for s in range(live)])
        r_pi = np.array([r[s, policy[s]] for s in range(live)])
        v = np.linalg.solve(np.eye(live) - gamma * p_pi, r_pi)
        v_full = np.append(v, 0.0)
        q = r[:live] + gamma * np.einsum("ska,k->sa", p[:live], v_full)
        new = np.argmax(q, axis=1)
        if np.array_equal(new, policy):
            return v_full, q
        policy = new


@pytest.mark.parametrize("in_place", [False, True])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_values_and_policy_match_an_independent_mdp_solver(seed: int, in_place: bool) -> None:
    config = replace(SMALL, vi_tolerance=1e-11, in_place_sweeps=in_place)
    learner = Learner(config, np.random.default_rng(seed))
    _feed_random_model(learner, np.random.default_rng(100 + seed), 2000)
    learner.end_episode()
    p, r = learner.export_model()
    v_ref, q_ref = _policy_iteration(p, r, config.gamma)
    np.testing.assert_allclose(learner.values, v_ref, atol=1e-7)
    np.testing.assert_allclose(learner.q_values[:-1], q_ref, atol=1e-7)
    clear = np.abs(q_ref[:, 1] - q_ref[:, 0]) > 1e-6
    assert np.array_equal(learner.policy[:-1][clear], np.argmax(q_ref, axis=1)[clear])


def test_printed_alg4_form_equals_the_standard_backup_on_visited_rows() -> None:
    standard = Learner(SMALL, np.random.default_rng(0))
    printed = Learner(replace(SMALL, alg4_printed=True), np.random.default_rng(0))
    for learner in (standard, printed):
        _feed_random_model(learner, np.random.default_rng(5), 300, every_pair=False)
        learner.end_episode()
    visited = standard.counts.sum(axis=1) > 0
    assert visited.any() and not visited[:-1].all()
    np.testing.assert_allclose(printed.q_values[visited], standard.q_values[visited], atol=1e-9)


def test_sparse_and_dense_models_give_the_same_policy() -> None:
    dense = Learner(replace(SMALL, model_form=ModelForm.DENSE), np.random.default_rng(3))
    sparse = Learner(replace(SMALL, model_form=ModelForm.SPARSE, sparse_slots=4), np.random.default_rng(3))
    for learner in (dense, sparse):
        _feed_random_model(learner, np.random.default_rng(9), 5000)
        learner.end_episode()
    assert np.array_equal(dense.counts, sparse.counts)
    np.testing.assert_allclose(dense.q_values, sparse.q_values, atol=1e-9)
    assert np.array_equal(dense.policy, sparse.policy)


def test_memory_bytes_is_the_teensy_layout() -> None:
    rng = np.random.default_rng(0)
    dense = Learner(LearnerConfig(model_form=ModelForm.DENSE), rng)
    assert dense.memory_bytes == 101 * 101 * 2 * 2 + 101 * 2 * 4  # uint16 C[s,s',a] + float32 reward sums
    sparse = Learner(LearnerConfig(model_form=ModelForm.SPARSE, sparse_slots=12), rng)
    assert sparse.memory_bytes == 101 * 2 * 12 * (1 + 2) + 101 * 2 * 4  # uint8 index + uint16 count
    big = Learner(LearnerConfig(actuator_bins=3, sparse_slots=12), rng)
    assert big.memory_bytes == 301 * 2 * 12 * (2 + 2) + 301 * 2 * 4  # 301 states need uint16 indices
    assert dense.memory_bytes > 40_000 > 10_000 > sparse.memory_bytes


def test_untried_pairs_are_optimistic_unless_told_otherwise() -> None:
    optimistic = Learner(SMALL, np.random.default_rng(0))
    pessimistic = Learner(replace(SMALL, untried_q_value=-50.0), np.random.default_rng(0))
    for learner in (optimistic, pessimistic):
        learner.observe(0, 0, -0.5, 1)
        learner.end_episode()
    assert optimistic.policy[0] == 1  # the untried a2 (Q = 0) beats a tried a1 with negative reward
    assert pessimistic.policy[0] == 0


def test_argmin_reading_picks_the_worse_action() -> None:
    good = Learner(SMALL, np.random.default_rng(0))
    literal = Learner(replace(SMALL, policy_argmin=True), np.random.default_rng(0))
    for learner in (good, literal):
        for _ in range(5):
            learner.observe(0, 0, -0.1, 0)
            learner.observe(0, 1, -10.0, terminal_state(SMALL))
        learner.end_episode()
    assert good.policy[0] == 0 and literal.policy[0] == 1


def test_ties_are_broken_at_random_or_always_to_a1() -> None:
    random_ties = Learner(LearnerConfig(), np.random.default_rng(0))
    assert 20 < random_ties.policy[:-1].sum() < 80
    always_a1 = Learner(LearnerConfig(random_ties=False), np.random.default_rng(0))
    assert always_a1.policy.sum() == 0


def test_exploration_decays_linearly_and_flips_the_greedy_action() -> None:
    learner = Learner(LearnerConfig(), np.random.default_rng(0))
    assert learner.p_explore == pytest.approx(0.10)
    greedy = learner.policy[7]
    flips = sum(learner.act(7) != greedy for _ in range(20_000))
    assert flips / 20_000 == pytest.approx(0.10, abs=0.01)
    for _ in range(500):
        learner.end_episode()
    assert learner.episode == 500 and learner.p_explore == pytest.approx(0.05)
    literal = Learner(LearnerConfig(explore_literal_gt=True), np.random.default_rng(0))
    flipped = sum(literal.act(7) != literal.policy[7] for _ in range(2000)) / 2000
    assert flipped == pytest.approx(0.9, abs=0.03)


def test_counts_saturate_without_losing_the_proportions() -> None:
    learner = Learner(replace(SMALL, model_form=ModelForm.DENSE), np.random.default_rng(0))
    for i in range(70_000):
        learner.observe(0, 0, -0.2, 1 if i % 4 else 2)
    assert learner.counts.max() <= 65535
    # float32 reward sums (as on the Teensy) keep the mean to about 1e-3 over 65535 additions.
    p, r = learner.export_model()
    assert p[0, 1, 0] == pytest.approx(0.75, abs=1e-3) and r[0, 0] == pytest.approx(-0.2, abs=1e-3)


def test_state_index_grid_and_terminal() -> None:
    config = LearnerConfig()
    assert n_states(config) == 101 and terminal_state(config) == 100
    assert state_index(1.0, 0.0, 1.0, config) == 5 * 10 + 5
    assert state_index(1.0 - 0.099, -0.039, 1.0, config) == 0
    assert state_index(1.0 + 0.1, 0.0, 1.0, config) == 100
    assert state_index(1.0, 0.05, 1.0, config) == 100
    depth_only = LearnerConfig(depth_only_terminal=True)
    assert state_index(1.0, 0.05, 1.0, depth_only) == 5 * 10 + 9  # open-ended edge velocity bin
    with_actuator = LearnerConfig(actuator_bins=3)
    assert state_index(1.0, 0.0, 1.0, with_actuator, actuator_fraction=0.9) == (2 * 10 + 5) * 10 + 5


def test_bad_configuration_and_bad_calls_are_refused() -> None:
    with pytest.raises(LearnerConfigError):
        LearnerConfig(gamma=1.0)
    learner = Learner(SMALL, np.random.default_rng(0))
    with pytest.raises(LearningError):
        learner.observe(0, 2, 0.0, 1)
    with pytest.raises(LearningError):
        learner.act(terminal_state(SMALL))
