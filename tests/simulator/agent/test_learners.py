"""The virtual agent runs the shared-model learners (`dive sim --learner ...`), velocity input included."""

from __future__ import annotations

import numpy as np
import pytest

from learning import Learner, learner_preset
from protocol import DumpKind
from simulator.agent.dumps import DumpStore, snapshot_bytes
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.mission import MissionConfig
from simulator.agent.program import OnboardProgram
from simulator.parameters import preset
from tests.simulator.checking_downlink import CheckingDownlink


@pytest.mark.slow  # two agents of 8000 steps each
@pytest.mark.parametrize("learner", ["shared-bins13-diff4", "shared-dirichlet", "shared-z20-bins7-diff8-term100-vpen1",
                                     "shared-z20-bins7-filter-term100-vpen1"])
def test_the_agent_learns_with_the_shared_model(learner: str) -> None:
    params, config = preset("hardware"), learner_preset(learner)
    rng = np.random.default_rng(2)
    down = CheckingDownlink()
    program = OnboardProgram(params, config, MissionConfig(), SimulatedHardware(params, rng), rng, down)
    down.program = program
    program.start(0)
    depths: list[float] = []
    velocities: list[float] = []
    true_velocities: list[float] = []
    for _ in range(8000):
        program.step()
        if program.mode.name == "LEARNING" and program.learner.episode == 0:
            depths.append(program.depth_m)
            velocities.append(program.velocity_mps)
            true_velocities.append(program.hw.plant.velocity_mps)
    assert program.learner.episode > 0 and down.samples > 5000
    expected_bytes = {"shared-bins13-diff4": 15604, "shared-dirichlet": 1204 + 101 * 2 * 12 * 3,
                      "shared-z20-bins7-diff8-term100-vpen1": 11204, "shared-z20-bins7-filter-term100-vpen1": 11204}
    assert program.learner.memory_bytes == expected_bytes[learner]
    # Every learning step saw a velocity; with diff4 it is the agent's own 4-step depth difference.
    k, dt = config.velocity_diff_steps, params.control_period_s
    if k:
        got = np.array(velocities[k + 1:])
        expected = (np.array(depths[k + 1:]) - np.array(depths[1:-k])) / (k * dt)
        np.testing.assert_allclose(got, expected, atol=1e-12)
    if config.filter_depth_gain:  # the filter: within a few mm/s of the hull's true velocity from the first steps
        error = np.array(velocities[5:]) - np.array(true_velocities[5:])
        assert np.sqrt(np.mean(error * error)) < 0.003
    values = program.learner.values
    assert np.any(values[:-1] != 0.0)  # planning ran on what the shared model learnt


def test_shared_model_q_values_snapshot_is_rendered_live() -> None:
    """SPEC.md 10/13: a shared model's Q_VALUES goes STALE when the model changes (it is not a copy); the
    per-state learners' Q_VALUES is a copy and stays."""
    for name, live in (("shared", True), ("paper", False)):
        learner = Learner(learner_preset(name), np.random.default_rng(0))
        learner.observe(5, 1, -0.05, 6)
        store = DumpStore()
        q = store.take(learner, DumpKind.Q_VALUES)
        values = store.take(learner, DumpKind.VALUES)
        # Live: Q from the model as it is now (one transition, not yet planned): the firmware's rendering.
        expected = learner.live_q_values() if live else learner.q_values
        assert q.data == expected.astype("<f4").tobytes() == snapshot_bytes(learner, DumpKind.Q_VALUES)
        store.model_changed()
        assert (store.get(q.dump_id) is None) == live
        assert store.get(values.dump_id) is not None
