"""The C learner (firmware/src/learner.c) against the Python one (learning/) on the same transitions.

The transitions are recorded from the Python learner acting in the simulator's environment; the C
learner replays them (observe, end_episode, planning to completion). Both draw from the same SplitMix64
stream (the C is seeded with the Python learner's initial stream state), so ties broken at random and
exploration flips are the same draws: the C learner must choose the very actions the Python one chose.
A second run uses the deterministic tie rule (random_ties off: a tie picks a1 in both).
"""

from __future__ import annotations

import ctypes
from dataclasses import replace

import numpy as np
import pytest

from learning import Learner, LearnerConfig, learner_memory_bytes, n_states
from learning.presets import learner_preset
from learning.rng import new_stream
from tests.firmware.ctl_lib import LearnerConfigC, Recording, build_ctl_library, c_config, c_field_names, record_python

SEED = 20261123
# float32 (C) against float64 (Python): values accumulate rounding over hundreds of sweeps, and the
# stopping sweep may differ by one near the tolerance (1e-4), so values agree to a few 1e-4.
VALUE_ATOL = 2e-3
# A policy may differ only where Python's two Q values are this close (a float32 near-tie).
NEAR_TIE = 1e-3


@pytest.fixture(scope="module")
def ctl(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    return build_ctl_library(tmp_path_factory.mktemp("ctl"))


def test_default_config_is_the_python_default(ctl: ctypes.CDLL) -> None:
    c = LearnerConfigC()
    ctl.learner_default_config(ctypes.byref(c))
    expected = c_config(ctl, LearnerConfig())
    for name in (f[0] for f in LearnerConfigC._fields_):
        assert getattr(c, name) == getattr(expected, name), name


@pytest.mark.parametrize("config", [
    LearnerConfig(),
    learner_preset("actuator3"),
    LearnerConfig(z_cells=20, zdot_cells=20),  # 401 states: two-byte successor indices
    LearnerConfig(sparse_slots=4, actuator_bins=2),
], ids=["paper", "actuator3", "wide", "slots4"])
def test_memory_bytes_equal_python_figure(ctl: ctypes.CDLL, config: LearnerConfig) -> None:
    c = c_config(ctl, config)
    assert ctl.learner_memory_bytes(ctypes.byref(c)) == learner_memory_bytes(config)
    # On top: the Jacobi sweep buffer, one float per state (Python's figure leaves it out).
    total = ctl.learner_total_bytes(ctypes.byref(c))
    assert total == learner_memory_bytes(config) + 4 * n_states(config)
    fits = total <= ctl.learner_arena_bytes()
    assert ctl.learner_configure(ctypes.byref(c)) == fits
    if fits:
        assert ctl.learner_n_states() == n_states(config)
        assert ctl.learner_used_bytes() == total  # the arrays as carved take exactly that


def test_oversized_model_refused(ctl: ctypes.CDLL) -> None:
    paper = c_config(ctl, LearnerConfig())
    assert ctl.learner_configure(ctypes.byref(paper))
    big = c_config(ctl, LearnerConfig(z_cells=50, zdot_cells=50, actuator_bins=9))  # 22 501 states
    assert not ctl.learner_configure(ctypes.byref(big))
    assert ctl.learner_n_states() == 101  # the old learner stays


def replay_in_c(lib: ctypes.CDLL, config: LearnerConfig, rec: Recording, slice_sweeps: int) -> None:
    """Replay rec into the C learner, checking actions, values, Q and policy after every episode."""
    c = c_config(lib, config)
    lib.learner_seed(int(new_stream(np.random.default_rng(SEED))[0]))
    assert lib.learner_configure(ctypes.byref(c))
    s_count = n_states(config)
    states = range(s_count)
    for ep, steps in enumerate(rec.episodes):
        prev_q = rec.q[ep]
        for state, action, reward, next_state, _ in steps:
            chosen = lib.learner_act(state)
            if abs(prev_q[state, 1] - prev_q[state, 0]) > NEAR_TIE:
                assert chosen == action, f"episode {ep + 1}: C chose {chosen} in state {state}"
            lib.learner_observe(state, action, reward, next_state)
        lib.learner_end_episode()
        slices = 1
        while not lib.learner_plan_slice(slice_sweeps):
            slices += 1
        sweeps = lib.learner_last_sweeps()
        assert slices == -(-sweeps // slice_sweeps) or sweeps % slice_sweeps == 0
        assert abs(sweeps - rec.sweeps[ep]) <= 2, f"episode {ep + 1}: {sweeps} sweeps, Python {rec.sweeps[ep]}"
        values = np.array([lib.learner_value(s) for s in states])
        np.testing.assert_allclose(values, rec.values[ep], atol=VALUE_ATOL, rtol=0)
        q = np.array([[lib.learner_q(s, a) for a in (0, 1)] for s in states])
        np.testing.assert_allclose(q, rec.q[ep + 1], atol=VALUE_ATOL, rtol=0)
        policy = np.array([lib.learner_policy(s) for s in states])
        gap = np.abs(rec.q[ep + 1][:, 1] - rec.q[ep + 1][:, 0])
        clear = (gap > NEAR_TIE) | (gap == 0.0)  # exact ties: the same draw decides in both
        assert np.array_equal(policy[clear], rec.policy[ep][clear]), f"episode {ep + 1}: policies differ"
        assert lib.learner_episode() == ep + 1
        assert lib.learner_p_explore() == pytest.approx(0.1 - 0.1 * (ep + 1) / 1000, abs=1e-7)
    # The model itself: every count the Python learner holds, the C holds.
    final = Learner(config, np.random.default_rng(SEED))
    for steps in rec.episodes:
        for state, action, reward, next_state, _ in steps:
            final.observe(state, action, reward, next_state)
    counts = final.counts
    for s, s2, a in zip(*np.nonzero(counts), strict=True):
        assert lib.learner_count(a, s, s2) == counts[s, s2, a]


@pytest.mark.slow
@pytest.mark.parametrize("name,random_ties,episodes,slice_sweeps", [
    ("paper", True, 60, 1),
    ("paper", False, 40, 7),
    ("actuator3", True, 40, 3),
])
def test_c_learner_follows_python(
    ctl: ctypes.CDLL, name: str, random_ties: bool, episodes: int, slice_sweeps: int
) -> None:
    config = replace(learner_preset(name), random_ties=random_ties)
    rec = record_python(config, "paper", episodes, SEED)
    assert sum(len(e) for e in rec.episodes) > 500  # enough learning to make values and policy nontrivial
    replay_in_c(ctl, config, rec, slice_sweeps)


def test_state_index_and_reward_match(ctl: ctypes.CDLL) -> None:
    from learning import state_index
    from learning.acting import reward_kernel
    from learning.config import kernel_spec

    rng = np.random.default_rng(SEED)
    for config in (LearnerConfig(), learner_preset("actuator3"), LearnerConfig(depth_only_terminal=True)):
        c = c_config(ctl, config)
        assert ctl.learner_configure(ctypes.byref(c))
        spec = kernel_spec(config)
        for _ in range(2000):
            # float32 inputs, so both sides see the same numbers
            depth, vel, frac = (float(np.float32(x)) for x in (
                0.4 + rng.uniform(-0.12, 0.12), rng.uniform(-0.05, 0.05), rng.uniform(-1.2, 1.2)))
            target = float(np.float32(0.4))
            expected = state_index(depth, vel, target, config, frac)
            got = ctl.learner_state(depth, vel, target, frac)
            if got != expected:
                # only where float32 rounding moves a value across a cell edge
                edges_z = (depth - target + config.z_tol_m) / (2 * config.z_tol_m) * config.z_cells
                edges_v = (vel + config.zdot_tol_mps) / (2 * config.zdot_tol_mps) * config.zdot_cells
                edges_b = (frac + 1.0) / 2.0 * config.actuator_bins
                near = min(abs(x - round(x)) for x in (edges_z, edges_v, edges_b))
                assert near < 1e-5, (depth, vel, frac, got, expected)
            r = ctl.learner_reward(depth, target, got)
            assert r == pytest.approx(reward_kernel(depth, target, got, spec), abs=1e-6)


def test_field_names_cover_python_config() -> None:
    """Every LearnerConfig field has its C twin (model_form is the sparse form the firmware always uses)."""
    c_names = {f[0] for f in LearnerConfigC._fields_}
    for name, c_name in c_field_names().items():
        assert c_name in c_names, f"LearnerConfig.{name} has no field {c_name} in learner_config_t"
    assert len(c_field_names()) == len(LearnerConfigC._fields_)  # and every C field has its Python twin


@pytest.mark.slow
def test_c_learner_draws_ties_per_step_as_python(ctl: ctypes.CDLL) -> None:
    """ties_per_step: a tied state is marked (2) at planning and its action drawn at each step, in both."""
    config = replace(learner_preset("paper"), ties_per_step=True)
    rec = record_python(config, "paper", 30, SEED)
    assert any((p == 2).any() for p in rec.policy)  # ties were left to the steps
    replay_in_c(ctl, config, rec, 5)
