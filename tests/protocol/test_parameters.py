"""The one parameter definition (protocol/parameters.py): names, ranges, f32 storage and the refusal rule."""

from __future__ import annotations

import math

import pytest

from protocol import Mode, ParamType, messages
from protocol.parameters import NAME_BYTES, PARAMS, f32, param


def test_names_fit_char24_and_defaults_lie_in_their_ranges() -> None:
    assert [p.index for p in PARAMS] == list(range(len(PARAMS)))
    for p in PARAMS:
        assert len(p.name.encode()) <= NAME_BYTES
        assert p.minimum <= p.default <= p.maximum
        if p.param_type == ParamType.F32:  # stored as f32, reported as the f32 widened exactly
            assert f32(p.default) == p.default and f32(p.minimum) == p.minimum and f32(p.maximum) == p.maximum


def test_spec_1_0_names_and_the_simulator_only_start_flag() -> None:
    assert param("surface_on_link_loss").param_type == ParamType.BOOL
    assert param("dump_each_episode").param_type == ParamType.BOOL
    at_rest = param("start_at_rest")
    assert at_rest.simulator_only and at_rest.firmware_range() == (0.0, 0.0)
    assert param("target_depth_m").default == 0.4000000059604645


@pytest.mark.parametrize(("name", "value", "why"), [
    ("gamma", math.nan, "finite"), ("gamma", math.inf, "finite"), ("gamma", 1.5, "outside"),
    ("max_episodes", 7.9, "integer"), ("dump_each_episode", 2, "outside"), ("dump_each_episode", 0.5, "integer"),
    ("z_cells", 0, "outside"), ("z_cells", 51, "outside"),
])
def test_refused_values_name_why(name: str, value: float, why: str) -> None:
    assert why in param(name).refusal(value)


def test_accepted_values_are_stored_as_the_agent_stores_them() -> None:
    gamma = param("gamma")
    assert gamma.refusal(0.9565) == "" and gamma.stored(0.9565) == f32(0.9565) != 0.9565
    assert param("gamma").refusal(0.999) == ""  # the f32-rounded bound itself
    assert param("max_episodes").stored(7.0) == 7.0


def test_refused_in_modes_follow_the_kind_of_parameter() -> None:
    learner = [p for p in PARAMS if p.learner]
    assert all(p.refused_in == (Mode.LEARNING, Mode.RECOVERING) for p in learner)
    for name in ("target_depth_m", "success_time_s", "control_dt_s", "action_step_deg", "action_win_deg"):
        assert param(name).refused_in == (Mode.LEARNING,)
    for name in ("link_timeout_s", "surface_on_link_loss", "dump_each_episode", "max_episodes", "start_at_rest"):
        assert param(name).refused_in == ()


def test_a_char24_text_longer_than_24_bytes_is_cut_at_a_character_boundary() -> None:
    long_name = "é" * 12 + "x"  # 25 bytes: cut to 24
    assert messages.ParamGet.unpack(messages.ParamGet(index=-1, name=long_name).pack()).name == "é" * 12
    odd = "x" + "é" * 12  # 25 bytes: a cut at 24 would split the last é, so 23 bytes go out
    assert messages.ParamGet.unpack(messages.ParamGet(index=-1, name=odd).pack()).name == "x" + "é" * 11
