"""Planning on growth in the C firmware (learner_config_t.plan_growth, shared_plan_due): the rule of learning/shared.py
plan_due on the same counts, the storage it takes, and the agent parameter that gives both agents hardware-lazyplan.
(The step-by-step differential run is tests/firmware/test_shared_learner.py test_c_plans_on_growth_as_python.)"""

from __future__ import annotations

import ctypes
from dataclasses import asdict, replace
from typing import Any

import numpy as np
import pytest

from learning import Learner, LearnerConfig, learner_preset, n_states
from learning.shared import shared_memory_bytes
from protocol import AckResult, FrameEncoder, FrameFlag, StreamDecoder, messages
from protocol.parameters import param
from simulator.parameters import preset
from simulator.serve.firmware_host import FirmwareAgent, load_library
from tests.firmware.core_build import use_firmware_cache
from tests.firmware.ctl_lib import HARDWARE_BY_PARAMS, BothAgents, build_ctl_library, c_config

# learning/config.py's reasons, which firmware/src/params.c gives too.
GROWTH_SHARED_ONLY = "planning on growth (plan_growth) is for the shared model only"
STOP_SHARED_ONLY = "the early planning stop (plan_stable_sweeps) is for the shared model only"
GROWTH = LearnerConfig(shared_model=True, plan_growth=0.25)


@pytest.fixture(scope="module")
def ctl(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    lib = build_ctl_library(tmp_path_factory.mktemp("growth"))
    lib.shared_plan_due.restype = ctypes.c_bool
    lib.shared_plan_due.argtypes = []
    return lib


def _whole_words(n_bytes: int) -> int:
    return (n_bytes + 3) // 4 * 4


def test_planning_on_growth_keeps_a_count_per_type_and_is_the_shared_models(ctl: ctypes.CDLL) -> None:
    """hardware-lazyplan's arena: hardware-fastplan's and a uint16 per type in whole words, which learning's
    shared_memory_bytes does not count; what learning/config.py refuses, learner_configure refuses."""
    config = learner_preset("hardware-lazyplan")
    c = c_config(ctl, config)
    model = shared_memory_bytes(config.z_cells, config.zdot_cells, config.actuator_bins, config.sparse_slots, False)
    states, types = n_states(config), config.zdot_cells * config.actuator_bins * 2
    policy, greedy = _whole_words(-(-states // 4)), _whole_words(-(-states // 8))
    assert ctl.learner_memory_bytes(ctypes.byref(c)) == model
    assert ctl.learner_total_bytes(ctypes.byref(c)) == model + policy + greedy + _whole_words(2 * types)
    assert ctl.learner_total_bytes(ctypes.byref(c)) == ctl.learner_total_bytes(
        ctypes.byref(c_config(ctl, learner_preset("hardware-fastplan")))) + 2 * types
    assert ctl.learner_configure(ctypes.byref(c))
    assert ctl.learner_used_bytes() == ctl.learner_total_bytes(ctypes.byref(c))
    paper = c_config(ctl, learner_preset("paper"))
    paper.plan_growth = 0.25  # without the shared model
    assert not ctl.learner_configure(ctypes.byref(paper))
    for bad in (-0.25, 100.5, float("nan"), float("inf")):
        c.plan_growth = bad
        assert not ctl.learner_configure(ctypes.byref(c)), bad
    c.plan_growth = 100.0
    assert ctl.learner_configure(ctypes.byref(c))


def _cell_state(config: LearnerConfig, iz: int, iv: int) -> int:
    return iz * config.zdot_cells + iv


def test_c_plan_due_is_python_plan_due(ctl: ctypes.CDLL) -> None:
    """The same transitions into both learners: both call a plan due at the same moments, at a type's first count,
    exactly at the bound (2 >= 0.25 x 8, counted over a skipped plan) and after a halving (what the type had is then
    taken as at most 1); a skipped plan starts no planning in C, a due one does; each type's count since the last
    plan is Python's throughout."""
    learner = Learner(GROWTH, np.random.default_rng(7))
    ctl.learner_seed(7)
    assert ctl.learner_configure(ctypes.byref(c_config(ctl, GROWTH)))
    types = GROWTH.zdot_cells * 2

    def count(n: int, iv: int = 5, action: int = 0) -> None:
        """n transitions of type (velocity cell iv, action) from depth cell 4 to depth cell 5, on both sides."""
        s, s_next = _cell_state(GROWTH, 4, iv), _cell_state(GROWTH, 5, iv)
        for _ in range(n):
            learner.observe(s, action, -0.01, s_next)
            ctl.learner_observe(s, action, -0.01, s_next)

    def end_episode() -> bool:
        """Both learners end an episode (C plans to completion); whether they planned (asserted the same)."""
        due = learner.plan_due()
        assert ctl.shared_plan_due() == due
        since = learner.arrays.model.since_plan
        assert [ctl.shared_type_since_plan(t) for t in range(types)] == since.tolist()
        learner.end_episode()
        ctl.learner_end_episode()
        assert ctl.learner_planning() == due
        while not ctl.learner_plan_slice(1000):
            pass
        assert (ctl.learner_last_sweeps() > 0) == (learner.last_sweeps > 0) == due
        assert [ctl.shared_type_since_plan(t) for t in range(types)] == since.tolist()
        return due

    assert not end_episode()  # nothing counted since the reset's plan
    count(1)
    assert end_episode()  # a type seen for the first time
    count(7)
    assert end_episode()  # 7 >= 0.25 x 1
    count(1)
    assert not end_episode()  # 1 < 0.25 x 8
    count(1)
    assert end_episode()  # the count since the last plan went on over the skip: 2 >= 0.25 x 8, exactly the bound
    count(65535 - 10)
    assert end_episode()  # the total at 65 535
    count(1)  # halves: 32 768 + 1
    assert learner.arrays.model.totals[5 * 2] == 32769 == ctl.shared_type_total(5 * 2)
    assert not end_episode()  # 1 < 0.25 x 32 768
    count(1, iv=2, action=1)
    assert end_episode()  # another type's first count, however large the others


def test_the_growth_parameter_gives_both_agents_hardware_lazyplan(tmp_path_factory: pytest.TempPathFactory) -> None:
    """PARAM_SET plan_growth = 0.25 on top of hardware-fastplan's parameters makes both agents' learner
    `hardware-lazyplan`; without the shared model both refuse it with one reason, both when it is set and when the
    shared model is switched off under it; 101 is refused by both."""
    use_firmware_cache(tmp_path_factory)
    lib = load_library()
    both = BothAgents(lib)
    program = both.program
    both.assert_refused_alone("plan_growth", 0.25, "plan_growth", GROWTH_SHARED_ONLY)
    # Both refuse 101 (an F32's range refusal: the Python agent's reason names the value, params.c's does not).
    c_verdict = both.set_c("plan_growth", 101)
    assert (c_verdict.result, c_verdict.reason) == (AckResult.BAD_VALUE, b"plan_growth: outside [0, 100]")
    index = param("plan_growth").index
    assert program.set_param(index, 101) == (AckResult.BAD_VALUE, "plan_growth: 101 outside [0, 100]")
    fastplan = (("plan_stable_sweeps", 2), ("plan_loose_tol", 0.05))
    for name, value in (*HARDWARE_BY_PARAMS, *fastplan, ("plan_growth", 0.25)):
        assert both.set(name, value) == (AckResult.ACCEPTED, b""), name
    config = learner_preset("hardware-lazyplan")
    assert config == replace(learner_preset("hardware-fastplan"), plan_growth=0.25)
    # The Python agent holds the table's values as f32 (0.25 exactly); the count per type fits the C learner's arena.
    both.assert_both_learn(config)
    assert program.config.plan_growth == 0.25
    # Without the shared model: the early stop's reason first (as learning/config.py checks it first), then this one.
    assert both.set("shared_model", 0) == (AckResult.BAD_VALUE, STOP_SHARED_ONLY.encode())
    assert both.set("plan_stable_sweeps", 0) == (AckResult.ACCEPTED, b"")
    assert both.set("shared_model", 0) == (AckResult.BAD_VALUE, GROWTH_SHARED_ONLY.encode())
    assert both.set("plan_growth", 0) == (AckResult.ACCEPTED, b"")
    off = replace(config, plan_stable_sweeps=0, plan_growth=0.0)
    assert asdict(program.config) == pytest.approx(asdict(off), rel=1e-7)
    both.assert_c_is(off)


def test_the_c_agent_learns_on_through_skipped_plans(tmp_path_factory: pytest.TempPathFactory) -> None:
    """The C agent (modes.c on the host build, the paper plant) set by PARAM_SET to the shared model with
    plan_growth 1 (UCRL2's doubling): episodes follow one another whether the plan after the last one ran or was
    skipped (nothing to wait for in RECOVERING); at an episode's start the last plan's sweeps are 0 after a skipped
    plan and > 0 after one that ran, and both happen, a plan after a skip included."""
    use_firmware_cache(tmp_path_factory)
    lib = load_library()  # the agent's own library (one per process): its learner is the agent's
    lib.learner_last_sweeps.restype = ctypes.c_uint32
    decoder = StreamDecoder()
    starts: list[tuple[int, int]] = []  # (episode, the sweeps of the plan before it)
    acks: list[Any] = []

    def wrote(wire: bytes) -> None:
        for frame in decoder.feed(wire):
            if isinstance(frame.message, messages.EpisodeStart):
                starts.append((frame.message.episode, lib.learner_last_sweeps()))
            elif isinstance(frame.message, messages.Ack):
                acks.append(frame.message.result)

    agent = FirmwareAgent(preset("paper"), np.random.default_rng(5), wrote, node_id=5, key=None, seed=5)
    encoder = FrameEncoder(first_seq=1)
    commands: list[Any] = [messages.ParamSet(index=-1, value=float(value), name=name)
                           for name, value in (("shared_model", 1), ("in_place_sweeps", 1), ("plan_growth", 1))]
    for message in (*commands, messages.StartLearning(max_episodes=0)):
        agent.receive(encoder.encode(message, int(FrameFlag.ACK_REQUESTED)).wire)
        for _ in range(20):
            agent.step()
    assert acks == [AckResult.ACCEPTED] * 4
    for _ in range(60_000):  # measured: 77 episodes, 14 plans after the first
        agent.step()
    assert [episode for episode, _ in starts] == list(range(1, len(starts) + 1)) and len(starts) >= 40
    sweeps = [n for _, n in starts[1:]]  # the first episode's: the reset's plan
    skipped = sum(n == 0 for n in sweeps)
    after_skip = sum(a == 0 < b for a, b in zip(sweeps, sweeps[1:], strict=False))
    assert skipped >= 10 and after_skip >= 3, sweeps
