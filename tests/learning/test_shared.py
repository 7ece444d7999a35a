"""The shared (relocatable) model: offsets, shifting, terminal successors, its layout and planning."""

from __future__ import annotations

import numpy as np
import pytest

from learning import Learner, LearnerConfig, learner_preset, model_memory_bytes
from learning.acting import TIED, select_action_kernel
from learning.config import kernel_spec
from learning.errors import LearnerConfigError
from learning.shared import FAR, cell_reward, raw_cell_kernel, state_cell_code


def _state(config: LearnerConfig, iz: int, iv: int, ib: int = 0) -> int:
    return (ib * config.z_cells + iz) * config.zdot_cells + iv


def _cell_centre(config: LearnerConfig, iz: int, iv: int) -> tuple[float, float]:
    dz = 2 * config.z_tol_m / config.z_cells
    dv = 2 * config.zdot_tol_mps / config.zdot_cells
    return -config.z_tol_m + (iz + 0.5) * dz, -config.zdot_tol_mps + (iv + 0.5) * dv


@pytest.mark.parametrize("bins, expected", [(1, 1204), (3, 3604), (13, 15604)])
def test_memory_bytes_of_the_teensy_layout(bins: int, expected: int) -> None:
    # 20 * bins types of 12 x {uint8 code, uint16 count} + uint16 total + uint16 evictions = 40 B,
    # and a float32 value for each of the 100 * bins + 1 states.
    config = learner_preset("shared", actuator_bins=bins)
    assert model_memory_bytes(config) == 20 * bins * 40 + (100 * bins + 1) * 4 == expected
    blended = learner_preset("shared", actuator_bins=bins, dirichlet_weight=5.0)
    per_slot = 3 if bins == 1 else 4
    assert model_memory_bytes(blended) == expected + (100 * bins + 1) * 2 * 12 * per_slot


def test_raw_cells_extend_beyond_the_region_and_match_live_states() -> None:
    config = LearnerConfig(shared_model=True)
    spec = kernel_spec(config)
    for iz, iv in ((0, 0), (4, 7), (9, 9)):
        z, v = _cell_centre(config, iz, iv)
        assert raw_cell_kernel(0.4 + z, v, 0.4, 0.0, spec) == state_cell_code(_state(config, iz, iv), spec)


def test_one_transition_teaches_every_depth_cell_and_leaving_is_terminal() -> None:
    config = LearnerConfig(shared_model=True, p_explore_start=0.0)
    learner = Learner(config, np.random.default_rng(0))
    spec = kernel_spec(config)
    terminal = 100
    # In cell (iz 5, iv 6), action 1 led one depth cell down and one velocity cell up.
    z, v = _cell_centre(config, 6, 7)
    cell = raw_cell_kernel(0.4 + z, v, 0.4, 0.0, spec)
    learner.observe(_state(config, 5, 6), 1, -0.01, _state(config, 6, 7), cell)
    learner.end_episode()
    q = learner.q_values
    gamma = config.gamma
    values = learner.values
    for iz in range(10):
        s = _state(config, iz, 6)
        nxt = _state(config, iz + 1, 7) if iz < 9 else terminal
        expected = float(cell_reward(nxt, spec)) + gamma * values[nxt]
        assert q[s, 1] == pytest.approx(expected)
        assert q[s, 0] == 0.0  # the untried type stays optimistic
    # A different velocity cell learnt nothing.
    assert q[_state(config, 5, 5), 1] == 0.0


def test_a_far_offset_is_terminal_and_a_terminal_successor_needs_its_cell() -> None:
    config = LearnerConfig(shared_model=True)
    learner = Learner(config, np.random.default_rng(0))
    spec = kernel_spec(config)
    with pytest.raises(Exception, match="next_cell"):
        learner.observe(_state(config, 5, 5), 0, -10.0, 100)
    # 30 cm below the target: far outside, a FAR offset, terminal from every cell.
    cell = raw_cell_kernel(0.7, 0.0, 0.4, 0.0, spec)
    learner.observe(_state(config, 5, 5), 0, -10.0, 100, cell)
    learner.end_episode()
    assert learner.q_values[_state(config, 0, 5), 0] == pytest.approx(config.terminal_reward)
    assert FAR == 255


def test_slot_evictions_are_counted() -> None:
    config = LearnerConfig(sparse_slots=2)
    learner = Learner(config, np.random.default_rng(0))
    for nxt in (1, 2, 3, 4):
        learner.observe(0, 0, -0.1, nxt)
    assert learner.evictions == 2


def test_dirichlet_blend_weights_local_counts_against_the_shared_prior() -> None:
    config = LearnerConfig(shared_model=True, dirichlet_weight=2.0, p_explore_start=0.0)
    learner = Learner(config, np.random.default_rng(0))
    spec = kernel_spec(config)
    a, b = _state(config, 5, 5), _state(config, 3, 5)
    # Local: from a, twice to a itself; shared (from b, another depth): one step up in velocity.
    learner.observe(a, 0, 0.0, a)
    learner.observe(a, 0, 0.0, a)
    learner.observe(b, 0, 0.0, _state(config, 3, 6))
    learner.end_episode()
    v, r = learner.values, lambda s: float(cell_reward(s, spec))
    # Shared histogram: offset (0, 0) twice, (0, +1) once; local at a: a twice; weight 2 -> local 2/4.
    p_self = 2 / 4 + 2 / 4 * 2 / 3
    p_up = 2 / 4 * 1 / 3
    up = _state(config, 5, 6)
    expected = p_self * (r(a) + config.gamma * v[a]) + p_up * (r(up) + config.gamma * v[up])
    assert learner.q_values[a, 0] == pytest.approx(expected)


def test_ties_per_step_are_drawn_at_every_step() -> None:
    config = LearnerConfig(ties_per_step=True, p_explore_start=0.0)
    learner = Learner(config, np.random.default_rng(0))
    assert (learner.policy[:-1] == TIED).all()  # nothing known: every state is tied
    actions = {learner.act(0) for _ in range(64)}
    assert actions == {0, 1}
    once = Learner(LearnerConfig(p_explore_start=0.0), np.random.default_rng(0))
    assert len({once.act(0) for _ in range(64)}) == 1
    spec = kernel_spec(config)
    rng = np.array([7], dtype=np.uint64)
    policy = np.array([TIED], dtype=np.int8)
    assert {select_action_kernel(policy, 0, 0.0, spec, rng) for _ in range(64)} == {0, 1}


def test_bounded_planning_stops_at_max_sweeps() -> None:
    config = LearnerConfig(shared_model=True, max_sweeps=3)
    learner = Learner(config, np.random.default_rng(0))
    spec = kernel_spec(config)
    z, v = _cell_centre(config, 5, 5)
    cell = raw_cell_kernel(0.4 + z, v, 0.4, 0.0, spec)
    for action in (0, 1):  # both tried: no optimistic 0 hides the self-loop's slowly converging value
        learner.observe(_state(config, 5, 5), action, 0.0, _state(config, 5, 5), cell)
    learner.end_episode()
    assert learner.last_sweeps == 3
    unbounded = Learner(LearnerConfig(shared_model=True), np.random.default_rng(0))
    for action in (0, 1):
        unbounded.observe(_state(config, 5, 5), action, 0.0, _state(config, 5, 5), cell)
    unbounded.end_episode()
    assert unbounded.last_sweeps > 100


def test_early_stop_ends_planning_once_the_greedy_policy_holds() -> None:
    """plan_stable_sweeps: the slowly converging self-loop of test_bounded_planning_stops_at_max_sweeps stops after
    the first sweep and two that change no greedy action, unless a sweep still moves a value by the loose bound."""
    sweeps = {}
    for loose in (1e6, 1e-9):
        config = LearnerConfig(shared_model=True, plan_stable_sweeps=2, plan_loose_tolerance=loose)
        learner = Learner(config, np.random.default_rng(0))
        z, v = _cell_centre(config, 5, 5)
        cell = raw_cell_kernel(0.4 + z, v, 0.4, 0.0, kernel_spec(config))
        for action in (0, 1):
            learner.observe(_state(config, 5, 5), action, -0.5, _state(config, 5, 5), cell)
        learner.end_episode()
        sweeps[loose] = learner.last_sweeps
    assert sweeps == {1e6: 3, 1e-9: sweeps[1e-9]} and sweeps[1e-9] > 100
    with pytest.raises(LearnerConfigError, match="shared model only"):
        LearnerConfig(plan_stable_sweeps=2)
    with pytest.raises(LearnerConfigError, match="must not be negative"):
        LearnerConfig(shared_model=True, plan_loose_tolerance=-1.0)


def test_the_velocity_penalty_charges_a_cell_its_centre_speed() -> None:
    plain = LearnerConfig(shared_model=True)
    charged = LearnerConfig(shared_model=True, velocity_penalty=2.0)
    for iz, iv in ((0, 0), (4, 7), (9, 9)):
        s = _state(plain, iz, iv)
        z, v = _cell_centre(plain, iz, iv)
        assert cell_reward(s, kernel_spec(plain)) == pytest.approx(-abs(z))
        assert cell_reward(s, kernel_spec(charged)) == pytest.approx(-abs(z) - 2.0 * abs(v))
    terminal = 100
    assert cell_reward(terminal, kernel_spec(charged)) == charged.terminal_reward


def test_the_hardware_preset_learner_is_what_its_name_says() -> None:
    config = learner_preset("shared-bins7-diff8-term100-vpen1")
    assert (config.actuator_bins, config.velocity_diff_steps) == (7, 8)
    assert (config.terminal_reward, config.velocity_penalty) == (-100.0, 1.0)
    assert config.shared_model and config.p_explore_start == 0.0
    # 7 bins: 140 types x 40 B + 701 float32 values, well inside the 16 KB goal.
    assert model_memory_bytes(config) == 140 * 40 + 701 * 4 == 8404


def test_finer_depth_cells_cost_only_values() -> None:
    config = learner_preset("shared-z20-bins7-diff8-term100-vpen1")
    assert config.z_cells == 20
    # The types do not depend on depth: 140 x 40 B as with 10 cells, and 1 401 float32 values.
    assert model_memory_bytes(config) == 140 * 40 + 1401 * 4 == 11204
