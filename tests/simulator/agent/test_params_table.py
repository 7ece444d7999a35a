"""The agent's parameter table: each PARAM_VALUE it sends carries the value stored at that moment."""

from __future__ import annotations

import numpy as np

from learning import LearnerConfig
from simulator.agent.mission import MissionConfig
from simulator.agent.params_table import ParamTable
from simulator.agent.program import Scope
from simulator.parameters import preset


def _table() -> ParamTable:
    return ParamTable({Scope.LEARNER: LearnerConfig(), Scope.PLANT: preset("hardware"), Scope.MISSION: MissionConfig()})


def test_a_parameter_value_message_follows_every_change_of_the_value() -> None:
    table = _table()
    index = table.lookup(-1, "target_depth_m")
    first = table.message(index)
    assert table.message(index) == first
    applied = table.set(index, 0.5)
    assert table.message(index).value == applied != first.value
    table.values[index] = first.value  # restored as set_param restores a refused value
    assert table.message(index) == first


def test_minus_zero_is_sent_as_minus_zero_after_zero() -> None:
    table = _table()
    index = table.lookup(-1, "target_depth_m")
    table.values[index] = 0.0
    zero = table.message(index).pack()
    table.values[index] = -0.0  # equal to 0.0, other bytes on the wire
    assert np.signbit(table.message(index).value)
    assert table.message(index).pack() != zero
