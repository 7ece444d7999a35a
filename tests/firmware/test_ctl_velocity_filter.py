"""The C velocity filter (observer.c vfilter_*) against the Python one (simulator/plant/episode.py), step by step.

The Python environment runs the filtering learner preset on a lagging, noisier port, swung back and forth; the C
filter gets the same measured depths and commands and must give the same velocity within float32 rounding, and
with it the C learner the same state at every step.
"""

from __future__ import annotations

import ctypes
from dataclasses import asdict, replace

import numpy as np
import pytest

from learning import VELOCITY_FILTER, LearnerConfig, learner_preset
from protocol import AckResult
from simulator.gym.task import DivingEnv
from simulator.parameters import preset, with_overrides
from simulator.serve.firmware_host import load_library
from tests.firmware.core_build import use_firmware_cache
from tests.firmware.ctl_lib import (
    HARDWARE_BY_PARAMS,
    BothAgents,
    VfilterState,
    build_ctl_library,
    c_config,
    vfilter_gains,
)

FILTER = "shared-z20-bins7-filter-term100-vpen1"
# The robust learner: its depth from the filter too (filter_depth_state); `hardware` plans on growth as well.
DEPTH_FILTER = "shared-z20-bins7-fdepth-term100-vpen1"
F32_ATOL_MPS = 2e-6  # float32 against float64 in a contracting filter: measured below 1e-7


@pytest.fixture(scope="module")
def ctl(tmp_path_factory: pytest.TempPathFactory) -> ctypes.CDLL:
    return build_ctl_library(tmp_path_factory.mktemp("ctl"))


def _near_a_cell_edge(depth: float, velocity: float, target: float, config: LearnerConfig) -> bool:
    """Where float32 rounding may move a value across a depth or velocity cell's edge (the actuator fraction is the
    same float on both sides)."""
    c = config
    edges = ((depth - target + c.z_tol_m) / (2 * c.z_tol_m) * c.z_cells,
             (velocity + c.zdot_tol_mps) / (2 * c.zdot_tol_mps) * c.zdot_cells)
    return min(abs(x - round(x)) for x in edges) < 1e-4


@pytest.mark.parametrize("learner", [FILTER, DEPTH_FILTER])
def test_c_filter_and_state_follow_python(ctl: ctypes.CDLL, learner: str) -> None:
    config = learner_preset(learner)
    params = with_overrides(preset("hardware"), {"pressure_lag_s": 0.2, "pressure_noise_pa": 13.0})
    assert ctl.learner_configure(ctypes.byref(c_config(ctl, config)))
    gains = vfilter_gains(config)
    env = DivingEnv(params, config)
    state = VfilterState()
    target = float(np.float32(params.target_depth_m))
    obs, info = env.reset(seed=5)
    ctl.vfilter_start(ctypes.byref(state), float(np.float32(obs[0])), 0.0)
    episodes, checked = 1, 0
    for k in range(1500):
        obs, _, terminated, truncated, info = env.step((k // 17) % 2)
        depth, offset = float(np.float32(obs[0])), float(np.float32(obs[2]))
        v_c = ctl.vfilter_update(ctypes.byref(state), ctypes.byref(gains), depth, offset, params.control_period_s)
        assert v_c == pytest.approx(obs[1], abs=F32_ATOL_MPS), k
        frac = offset / params.action_window_deg
        seen = state.z_m if config.filter_depth_state else depth  # the depth the learner sees
        if not _near_a_cell_edge(seen, v_c, target, config):
            assert ctl.learner_state(seen, v_c, target, float(np.float32(frac))) == info["state"], k
            checked += 1
        if terminated or truncated:
            obs, info = env.reset()
            ctl.vfilter_start(ctypes.byref(state), float(np.float32(obs[0])), 0.0)
            episodes += 1
    assert episodes > 1 and checked > 1400  # ends and restarts were crossed; the bias carried over them


def test_c_refuses_the_filter_with_the_depth_difference_as_python(ctl: ctypes.CDLL) -> None:
    config = learner_preset(FILTER)
    c = c_config(ctl, config)
    c.vel_diff_steps = 8
    assert not ctl.learner_configure(ctypes.byref(c))
    c = c_config(ctl, config)
    c.filter_bias_gain = -0.1
    assert not ctl.learner_configure(ctypes.byref(c))
    assert ctl.learner_configure(ctypes.byref(c_config(ctl, replace(config, filter_depth_gain=0.0))))


NOT_BOTH = "choose the velocity filter or the depth difference, not both"


def test_the_velocity_filter_parameter_gives_both_agents_the_filter_preset(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """PARAM_SET velocity_filter = 1 makes the C firmware's learner (params.c, the host build) and the Python agent's
    the hardware learner (the robust filter preset), gains and filtered depth included; with vel_diff_steps > 0 both
    refuse it, with one reason; 0 switches it off."""
    use_firmware_cache(tmp_path_factory)
    both = BothAgents(load_library())
    program = both.program
    assert both.set("vel_diff_steps", 8) == (AckResult.ACCEPTED, b"")
    assert both.set("velocity_filter", 1) == (AckResult.BAD_VALUE, NOT_BOTH.encode())
    assert program.table.value("velocity_filter") == 0.0 and program.config.filter_depth_gain == 0.0
    for name, value in (("vel_diff_steps", 0), *HARDWARE_BY_PARAMS):
        assert both.set(name, value) == (AckResult.ACCEPTED, b""), name
    config = learner_preset(DEPTH_FILTER)
    assert {name: getattr(config, name) for name in VELOCITY_FILTER} == VELOCITY_FILTER
    # The Python agent holds the table's values as f32 (0.1 as 0.10000000149011612), the filter's gains as given.
    assert asdict(program.config) == pytest.approx(asdict(config), rel=1e-7)
    assert {name: getattr(program.config, name) for name in VELOCITY_FILTER} == VELOCITY_FILTER
    assert program.restart_pending  # a learner parameter: the learner restarts
    both.assert_c_is(config)
    assert both.set("vel_diff_steps", 8) == (AckResult.BAD_VALUE, NOT_BOTH.encode())
    assert both.set("velocity_filter", 0) == (AckResult.ACCEPTED, b"")
    off = replace(config, **{name: type(value)(0) for name, value in VELOCITY_FILTER.items()})
    assert asdict(program.config) == pytest.approx(asdict(off), rel=1e-7)
    both.assert_c_is(off)
