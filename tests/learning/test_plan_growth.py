"""Planning on growth (LearnerConfig.plan_growth, learning/shared_plan.py plan_due): an episode's end plans only once
some type has counted, since the last plan, plan_growth times what it had then; the learner, the study and the
config."""

from __future__ import annotations

import numpy as np
import pytest

from learning import Learner, LearnerConfig, learner_preset
from learning.config import kernel_spec
from learning.errors import LearnerConfigError
from learning.model import ModelArrays
from learning.shared import allocate_arrays, raw_cell_kernel, record_shared
from learning.shared_plan import plan_due
from simulator.parameters import preset
from simulator.study.runner import run_study

GROWTH = LearnerConfig(shared_model=True, plan_growth=0.25)


def _state(config: LearnerConfig, iz: int, iv: int) -> int:
    return iz * config.zdot_cells + iv


def _cell(config: LearnerConfig, iz: int, iv: int) -> int:
    """The raw cell of a point inside cell (iz, iv), as record_shared takes a successor."""
    dz = 2 * config.z_tol_m / config.z_cells
    dv = 2 * config.zdot_tol_mps / config.zdot_cells
    z, v = -config.z_tol_m + (iz + 0.5) * dz, -config.zdot_tol_mps + (iv + 0.5) * dv
    return int(raw_cell_kernel(0.4 + z, v, 0.4, 0.0, kernel_spec(config)))


def _type(config: LearnerConfig, iv: int, action: int) -> int:
    """The type of velocity cell iv, actuator bin 0 and the action (learning/shared.py type_of)."""
    del config  # one actuator bin
    return iv * 2 + action


def _count(model: ModelArrays, config: LearnerConfig, n: int, iv: int = 5, action: int = 0) -> None:
    """n transitions of the type (velocity cell iv, bin 0, action), each from depth cell 4 to depth cell 5."""
    for _ in range(n):
        record_shared(model, _state(config, 4, iv), action, _cell(config, 5, iv), kernel_spec(config))


def test_a_type_is_due_once_its_count_grew_by_the_fraction_it_had_at_the_last_plan() -> None:
    spec = kernel_spec(GROWTH)
    model = allocate_arrays(spec)
    assert not plan_due(model, spec)  # nothing counted since the last plan
    _count(model, GROWTH, 1)
    assert plan_due(model, spec)  # a type seen for the first time always plans
    _count(model, GROWTH, 7)
    model.since_plan[:] = 0  # as a plan leaves it: 8 counted before
    _count(model, GROWTH, 1)
    assert not plan_due(model, spec)  # 1 < 0.25 x 8
    _count(model, GROWTH, 1)
    assert plan_due(model, spec)  # 2 >= 0.25 x 8: exactly at the bound
    # A first transition of another type is due however large the others are.
    model.since_plan[:] = 0
    _count(model, GROWTH, 1, iv=2, action=1)
    assert plan_due(model, spec)


def test_without_plan_growth_every_episode_plans() -> None:
    spec = kernel_spec(LearnerConfig(shared_model=True))
    assert plan_due(allocate_arrays(spec), spec)


def test_a_halved_type_plans_at_once() -> None:
    """Counts are halved when a total would pass 65535: what a type had at the last plan is then unknown, and the
    rule takes it as at most what was counted since (max(N - n, 1))."""
    spec = kernel_spec(GROWTH)
    model = allocate_arrays(spec)
    _count(model, GROWTH, 65535)
    model.since_plan[:] = 0
    _count(model, GROWTH, 1)  # halves: total 32768 + 1
    assert int(model.totals[_type(GROWTH, 5, 0)]) == 32769
    assert not plan_due(model, spec)  # 1 < 0.25 x 32768
    model.since_plan[_type(GROWTH, 5, 0)] = 20000  # as if 20 000 were counted since, and then halved
    assert plan_due(model, spec)  # 20 000 >= 0.25 x (32 769 - 20 000)


def test_the_learner_skips_a_plan_that_is_not_due_and_keeps_its_policy() -> None:
    learner = Learner(GROWTH, np.random.default_rng(3))
    s, cell = _state(GROWTH, 4, 5), _cell(GROWTH, 5, 5)
    for _ in range(40):
        learner.observe(s, 0, -0.1, _state(GROWTH, 5, 5), cell)
    assert learner.plan_due()
    learner.end_episode()
    assert learner.last_sweeps > 0
    policy, values = learner.policy, learner.values
    for _ in range(9):  # 9 < 0.25 x 40
        learner.observe(s, 0, -0.1, _state(GROWTH, 5, 5), cell)
    assert not learner.plan_due()
    learner.end_episode()
    assert learner.last_sweeps == 0 and learner.episode == 2
    assert np.array_equal(learner.policy, policy) and np.array_equal(learner.values, values)
    learner.observe(s, 0, -0.1, _state(GROWTH, 5, 5), cell)  # 10 >= 0.25 x 40
    learner.end_episode()
    assert learner.last_sweeps > 0


def test_the_study_plans_less_often_and_still_learns() -> None:
    """A small study of the lazy-planning learner next to its base: fewer plans (the counters the study reports),
    and trials that still reach the region's time limit."""
    params = preset("hardware-fast")
    lazy = run_study(params, learner_preset("hardware-lazyplan"), 4, 60, 5)
    every = run_study(params, learner_preset("hardware-fastplan"), 4, 60, 5)
    plans_lazy, plans_every = lazy.counters[:, 3], every.counters[:, 3]
    assert np.all(plans_every == 60)
    assert np.all(plans_lazy < 45) and np.all(plans_lazy >= 5)
    # Each trial still succeeds (300 s in the region) in the last 20 episodes.
    assert np.all((lazy.durations_s[:, -20:] >= params.episode_limit_s - 1e-6).any(axis=1))


def test_the_config_refuses_growth_without_the_shared_model_or_out_of_range() -> None:
    with pytest.raises(LearnerConfigError, match="shared model only"):
        LearnerConfig(plan_growth=0.25)
    for bad in (-0.1, 101.0):
        with pytest.raises(LearnerConfigError, match=r"plan_growth must lie in \[0, 100\]"):
            LearnerConfig(shared_model=True, plan_growth=bad)
