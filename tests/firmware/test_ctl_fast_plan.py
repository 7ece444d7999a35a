"""The agent parameters of planning's early stop give the C firmware's learner and the virtual agent's the same one."""

from __future__ import annotations

import ctypes
import shutil
import subprocess
from dataclasses import asdict, replace
from pathlib import Path

import pytest

from learning import learner_preset
from protocol import AckResult
from simulator.serve.firmware_host import load_library
from tests.firmware.core_build import use_firmware_cache
from tests.firmware.ctl_lib import FIRMWARE, HARDWARE_BY_PARAMS, BothAgents, c_config

# learning/config.py's reason, which firmware/src/params.c gives too.
SHARED_ONLY = "the early planning stop (plan_stable_sweeps) is for the shared model only"


def test_the_early_stop_parameters_give_both_agents_hardware_fastplan(
        tmp_path_factory: pytest.TempPathFactory) -> None:
    """PARAM_SET plan_stable_sweeps = 2 and plan_loose_tol = 0.05 on top of the hardware learner's parameters make
    both agents' learner `hardware-fastplan`; without the shared model both refuse a stop, with one reason, both
    when it is set and when the shared model is switched off under it; more than 100 sweeps is refused by both."""
    use_firmware_cache(tmp_path_factory)
    lib = load_library()
    both = BothAgents(lib)
    program = both.program
    both.assert_refused_alone("plan_stable_sweeps", 2, "plan_stable_sweeps", SHARED_ONLY)
    assert both.set("plan_stable_sweeps", 101) == (AckResult.BAD_VALUE, b"plan_stable_sweeps: 101 outside [0, 100]")
    # The tolerance alone changes no plan: any learner takes it.
    assert both.set("plan_loose_tol", 0.05) == (AckResult.ACCEPTED, b"")
    for name, value in (*HARDWARE_BY_PARAMS, ("plan_stable_sweeps", 2)):
        assert both.set(name, value) == (AckResult.ACCEPTED, b""), name
    config = learner_preset("hardware-fastplan")
    assert (config.plan_stable_sweeps, config.plan_loose_tolerance) == (2, 0.05)
    # The Python agent holds the table's values as f32 (0.05 as 0.05000000074505806); the early stop's bits per state
    # fit the C learner's arena.
    both.assert_both_learn(config)
    assert both.set("shared_model", 0) == (AckResult.BAD_VALUE, SHARED_ONLY.encode())
    assert both.set("plan_stable_sweeps", 0) == (AckResult.ACCEPTED, b"")
    off = replace(config, plan_stable_sweeps=0)
    assert asdict(program.config) == pytest.approx(asdict(off), rel=1e-7)
    both.assert_c_is(off)


def test_the_teensy_hardware_variant_has_room_for_the_early_stop(tmp_path: Path,
                                                                 tmp_path_factory: pytest.TempPathFactory) -> None:
    """The Teensy build's `shared-z20` variant (boards/teensy/teensy.mk) reserves, by its arena_size tool, exactly
    what `hardware-lazyplan`'s learner needs (learner_total_bytes), the early stop's greedy bits and planning on
    growth's counts per type included: more than `hardware-fastplan`, more again than `hardware`, so the robot
    refuses neither plan_stable_sweeps nor plan_growth for want of storage."""
    for tool in ("make", "cc"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not on PATH")
    tool = tmp_path / "host" / "arena_size"
    subprocess.run(["make", "-s", "-C", str(FIRMWARE), f"BUILD={tmp_path}", str(tool)], check=True, timeout=120)
    reserved = int(subprocess.run([str(tool), "20", "10", "7", "1"], capture_output=True, text=True,
                                  check=True).stdout.split()[0])
    use_firmware_cache(tmp_path_factory)
    lib = load_library()
    lib.learner_total_bytes.restype = ctypes.c_uint32

    def needs(name: str) -> int:
        return int(lib.learner_total_bytes(ctypes.byref(c_config(lib, learner_preset(name)))))

    full_plans = needs("shared-z20-bins7-fdepth-term100-vpen1")
    assert reserved == needs("hardware-lazyplan") > needs("hardware-fastplan") > full_plans
