"""The ground's bound on an announced snapshot size follows the agent's RAM budget (SPEC.md sections 10 and 13)."""

from __future__ import annotations

from dataclasses import replace

from groundstation.session.dumps import UNKNOWN_GRID_STATES, snapshot_bytes
from learning import LearnerConfig
from learning.config import n_states
from learning.learner import learner_memory_bytes
from protocol import DumpKind
from protocol.parameters import RAM_BUDGET_BYTES, param, snapshot_ram_bytes


def largest_states_that_fit(shared_model: bool) -> int:
    """The largest S any parameter combination within the SPEC ranges gives that the RAM budget admits."""
    top = {name: int(param(name).maximum) for name in ("z_cells", "zdot_cells", "act_bins")}
    base = replace(LearnerConfig(), shared_model=shared_model)
    best = 0
    for bins in range(1, top["act_bins"] + 1):
        for zdot in range(1, top["zdot_cells"] + 1):
            for z in range(top["z_cells"], 0, -1):  # the first that fits is this (bins, zdot)'s largest
                config = replace(base, z_cells=z, zdot_cells=zdot, actuator_bins=bins)
                states = n_states(config)
                if learner_memory_bytes(config) + snapshot_ram_bytes(states, shared_model) <= RAM_BUDGET_BYTES:
                    best = max(best, states)
                    break
    return best


def test_an_agent_not_yet_asked_is_bounded_by_the_largest_grid_the_budget_admits() -> None:
    assert largest_states_that_fit(shared_model=False) == 316
    assert largest_states_that_fit(shared_model=True) == UNKNOWN_GRID_STATES == 2071
    assert snapshot_bytes(DumpKind.COUNTS, UNKNOWN_GRID_STATES) == 17_156_164  # SPEC.md section 10 states it
