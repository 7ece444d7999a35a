"""Builds fwctl's C modules (observer, recovery, learner, plant, sensor) into a host library for ctypes."""

from __future__ import annotations

import ctypes
import shutil
import struct
import subprocess
from collections.abc import Callable
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np
import pytest

from learning import Learner, LearnerConfig
from protocol import AckResult, Mode
from protocol.parameters import param
from simulator.gym.task import DivingEnv
from simulator.parameters import preset
from tests.simulator.agent_trace import in_process_agent

FIRMWARE = Path(__file__).resolve().parents[2] / "firmware"
SOURCES = ("observer", "recovery", "rng", "learner", "learner_model", "learner_plan", "learner_state", "shared",
           "shared_plan", "plant", "sensor")


class SmoState(ctypes.Structure):
    _fields_ = [("x1_m", ctypes.c_float), ("x2_mps", ctypes.c_float)]


class SmoGains(ctypes.Structure):
    _fields_ = [("rho_mps", ctypes.c_float), ("tau_s", ctypes.c_float), ("phi_m", ctypes.c_float)]


class VfilterState(ctypes.Structure):
    _fields_ = [("z_m", ctypes.c_float), ("v_mps", ctypes.c_float), ("bias_mps2", ctypes.c_float)]


class VfilterGains(ctypes.Structure):
    _fields_ = [(name, ctypes.c_float) for name in (
        "depth_gain", "velocity_gain", "bias_gain", "accel_per_deg", "drag_per_m")]


def vfilter_gains(config: LearnerConfig) -> VfilterGains:
    """observer.c's filter gains of a learner configuration (learning/config.py's filter_* fields)."""
    return VfilterGains(config.filter_depth_gain, config.filter_velocity_gain, config.filter_bias_gain,
                        config.filter_accel_per_deg, config.filter_drag_per_m)


class RecoveryParams(ctypes.Structure):
    _fields_ = [(name, ctypes.c_float) for name in (
        "lambda_per_s", "phi_mps", "gain_deg", "avg_time_s", "settle_depth_m", "settle_velocity_mps",
        "settle_time_s", "give_up_s", "alpha_max_deg", "near_gain_deg", "near_phi_mps",
    )]


class RecoveryState(ctypes.Structure):
    _fields_ = [("avg_deg", ctypes.c_float), ("calm_s", ctypes.c_float), ("elapsed_s", ctypes.c_float)]


class LearnerConfigC(ctypes.Structure):
    _fields_ = [
        ("z_cells", ctypes.c_uint8), ("zdot_cells", ctypes.c_uint8), ("act_bins", ctypes.c_uint8),
        ("slots", ctypes.c_uint8), ("z_tol_m", ctypes.c_float), ("zdot_tol_mps", ctypes.c_float),
        ("gamma", ctypes.c_float), ("vi_tol", ctypes.c_float), ("term_reward", ctypes.c_float),
        ("p_explore_start", ctypes.c_float), ("p_explore_end", ctypes.c_float),
        ("explore_decay_episodes", ctypes.c_uint32), ("untried_q", ctypes.c_float),
        ("known_count", ctypes.c_uint16), ("random_ties", ctypes.c_bool),
        ("depth_only_terminal", ctypes.c_bool), ("in_place_sweeps", ctypes.c_bool),
        ("explore_literal_gt", ctypes.c_bool), ("policy_argmin", ctypes.c_bool),
        ("alg4_printed", ctypes.c_bool), ("max_sweeps", ctypes.c_uint32),
        ("shared_model", ctypes.c_bool), ("ties_per_step", ctypes.c_bool), ("dirichlet_w", ctypes.c_float),
        ("count_bonus", ctypes.c_float), ("vel_diff_steps", ctypes.c_uint8), ("vel_penalty", ctypes.c_float),
        ("filter_depth_gain", ctypes.c_float), ("filter_velocity_gain", ctypes.c_float),
        ("filter_bias_gain", ctypes.c_float), ("filter_accel_per_deg", ctypes.c_float),
        ("filter_drag_per_m", ctypes.c_float), ("filter_depth_state", ctypes.c_bool),
        ("plan_stable_sweeps", ctypes.c_uint16),
        ("plan_loose_tolerance", ctypes.c_float), ("plan_growth", ctypes.c_float), ("fine_step_deg", ctypes.c_float),
        ("fine_speed_mps", ctypes.c_float), ("fine_reversal_deg", ctypes.c_float),
    ]


# LearnerConfig fields that learner_config_t names otherwise; every other field has its C twin under its own name,
# but model_form (the firmware's model is always the sparse form) and issue 43's screened study options (a hold and the
# re-centred window, docs/learners-hold.md: no agent has them, the virtual agent refuses them).
C_NAMES = {"sparse_slots": "slots", "actuator_bins": "act_bins", "vi_tolerance": "vi_tol",
           "terminal_reward": "term_reward", "untried_q_value": "untried_q", "dirichlet_weight": "dirichlet_w",
           "velocity_diff_steps": "vel_diff_steps", "velocity_penalty": "vel_penalty"}
NO_C_TWIN = ("model_form", "hold_depth_m", "hold_speed_mps", "hold_lash_deg", "neutral_gain")


def c_field_names() -> dict[str, str]:
    """LearnerConfig field -> its learner_config_t field, for every field that has one."""
    return {f.name: C_NAMES.get(f.name, f.name) for f in fields(LearnerConfig) if f.name not in NO_C_TWIN}


def c_config(lib: ctypes.CDLL, config: LearnerConfig) -> LearnerConfigC:
    """The Python config as learner_config_t: the C default, then every LearnerConfig field at its C name."""
    c = LearnerConfigC()
    lib.learner_default_config(ctypes.byref(c))
    for name, c_name in c_field_names().items():  # test_field_names_cover_python_config: each c_name exists
        setattr(c, c_name, getattr(config, name))
    return c


class PlantParamsC(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in (
        "mass_kg", "added_mass_kg", "water_density_kgpm3", "gravity_mps2", "trim_error_fraction",
        "compressibility_m3pm", "drag_kgpm", "floor_depth_m", "stroke_volume_m3", "alpha_max_deg",
        "alpha_rate_dps", "substep_s", "backlash_deg", "dead_band_deg", "pressure_lag_s", "control_jitter_s",
    )]


class PlantStateC(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in (
        "z_m", "zdot_mps", "alpha_deg", "motor_deg", "sensed_z_m", "clock_s", "noise_pa", "last_read_s",
    )]


class SensorParamsC(ctypes.Structure):
    _fields_ = [(name, ctypes.c_double) for name in (
        "surface_pressure_pa", "water_density_kgpm3", "gravity_mps2", "noise_pa", "lsb_pa", "min_pa", "max_pa",
        "bias_pa", "drift_pa_per_s", "noise_corr_s", "depth_scale_error", "lag_s",
    )]


class RngC(ctypes.Structure):
    _fields_ = [("state", ctypes.c_uint64)]


_SIGNATURES: dict[str, tuple[object, list[object]]] = {
    "smo_reset": (None, [ctypes.POINTER(SmoState), ctypes.c_float]),
    "smo_update": (ctypes.c_float, [ctypes.POINTER(SmoState), ctypes.POINTER(SmoGains), ctypes.c_float,
                                    ctypes.c_float]),
    "vfilter_start": (None, [ctypes.POINTER(VfilterState), ctypes.c_float, ctypes.c_float]),
    "vfilter_update": (ctypes.c_float, [ctypes.POINTER(VfilterState), ctypes.POINTER(VfilterGains), ctypes.c_float,
                                        ctypes.c_float, ctypes.c_float]),
    "recovery_init": (None, [ctypes.POINTER(RecoveryState), ctypes.c_float]),
    "recovery_restart": (None, [ctypes.POINTER(RecoveryState)]),
    "recovery_step": (ctypes.c_float, [
        ctypes.POINTER(RecoveryState), ctypes.POINTER(RecoveryParams), ctypes.c_float, ctypes.c_float,
        ctypes.c_float, ctypes.c_float, ctypes.c_float, ctypes.POINTER(ctypes.c_bool),
        ctypes.POINTER(ctypes.c_bool),
    ]),
    "recovery_alpha_avg_deg": (ctypes.c_float, [ctypes.POINTER(RecoveryState)]),
    "learner_default_config": (None, [ctypes.POINTER(LearnerConfigC)]),
    "learner_memory_bytes": (ctypes.c_uint32, [ctypes.POINTER(LearnerConfigC)]),
    "learner_total_bytes": (ctypes.c_uint32, [ctypes.POINTER(LearnerConfigC)]),
    "learner_arena_bytes": (ctypes.c_uint32, []),
    "learner_used_bytes": (ctypes.c_uint32, []),
    "learner_configure": (ctypes.c_bool, [ctypes.POINTER(LearnerConfigC)]),
    "learner_seed": (None, [ctypes.c_uint64]),
    "learner_reset": (None, []),
    "learner_n_states": (ctypes.c_uint16, []),
    "learner_state": (ctypes.c_uint16, [ctypes.c_float] * 4),
    "learner_reward": (ctypes.c_float, [ctypes.c_float, ctypes.c_float, ctypes.c_uint16]),
    "learner_act": (ctypes.c_uint8, [ctypes.c_uint16]),
    "learner_step_deg": (ctypes.c_float, [ctypes.c_float, ctypes.c_float, ctypes.c_bool]),
    "learner_observe": (None, [ctypes.c_uint16, ctypes.c_uint8, ctypes.c_float, ctypes.c_uint16]),
    "learner_observe_cell": (None, [ctypes.c_uint16, ctypes.c_uint8, ctypes.c_float, ctypes.c_uint16,
                                    ctypes.c_uint32]),
    "learner_cell": (ctypes.c_uint32, [ctypes.c_float] * 4),
    "learner_evictions": (ctypes.c_uint32, []),
    "learner_plan_backups": (ctypes.c_bool, [ctypes.c_uint32]),
    "learner_planning": (ctypes.c_bool, []),
    "learner_end_episode": (None, []),
    "shared_slot": (ctypes.c_uint16, [ctypes.c_uint32, ctypes.c_uint32, ctypes.POINTER(ctypes.c_uint8)]),
    "shared_type_total": (ctypes.c_uint16, [ctypes.c_uint32]),
    "shared_type_evictions": (ctypes.c_uint16, [ctypes.c_uint32]),
    "shared_type_since_plan": (ctypes.c_uint16, [ctypes.c_uint32]),
    "shared_memory_bytes": (ctypes.c_uint32, [ctypes.POINTER(LearnerConfigC)]),
    "shared_total_bytes": (ctypes.c_uint32, [ctypes.POINTER(LearnerConfigC)]),
    "learner_plan_slice": (ctypes.c_bool, [ctypes.c_uint32]),
    "learner_last_sweeps": (ctypes.c_uint32, []),
    "learner_episode": (ctypes.c_uint32, []),
    "learner_p_explore": (ctypes.c_float, []),
    "learner_value": (ctypes.c_float, [ctypes.c_uint16]),
    "learner_policy": (ctypes.c_uint8, [ctypes.c_uint16]),
    "learner_q": (ctypes.c_float, [ctypes.c_uint16, ctypes.c_uint8]),
    "learner_count": (ctypes.c_uint16, [ctypes.c_uint8, ctypes.c_uint16, ctypes.c_uint16]),
    "plant_hardware_params": (None, [ctypes.POINTER(PlantParamsC)]),
    "plant_neutral_alpha_deg": (ctypes.c_double, [ctypes.POINTER(PlantParamsC)]),
    "plant_step": (None, [ctypes.POINTER(PlantStateC), ctypes.POINTER(PlantParamsC), ctypes.c_double,
                          ctypes.c_double]),
    "plant_place": (None, [ctypes.POINTER(PlantStateC), ctypes.c_double, ctypes.c_double, ctypes.c_double]),
    "plant_jittered_period_s": (ctypes.c_double, [ctypes.POINTER(PlantParamsC), ctypes.POINTER(RngC),
                                                  ctypes.c_double]),
    "sensor_hardware_params": (None, [ctypes.POINTER(SensorParamsC)]),
    "sensor_sense_pa": (ctypes.c_double, [ctypes.POINTER(SensorParamsC), ctypes.POINTER(RngC),
                                          ctypes.POINTER(PlantStateC)]),
    "sensor_read_pa": (ctypes.c_double, [ctypes.POINTER(SensorParamsC), ctypes.POINTER(RngC), ctypes.c_double]),
}


def build_ctl_library(out_dir: Path) -> ctypes.CDLL:
    """cc the modules into out_dir/libctl.so (the flags of the firmware build) and load it; skip without cc."""
    cc = shutil.which("cc")
    if cc is None:
        pytest.skip("cc not found: the C differential tests need a host C compiler")
    lib_path = out_dir / "libctl.so"
    sources = [str(FIRMWARE / "src" / f"{name}.c") for name in SOURCES]
    cmd = [cc, "-std=c99", "-O2", "-Wall", "-Wextra", "-Werror", "-Wdouble-promotion", "-shared", "-fPIC",
           "-o", str(lib_path), *sources, "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True)
    lib = ctypes.CDLL(str(lib_path))
    for name, (restype, argtypes) in _SIGNATURES.items():
        fn = getattr(lib, name)
        fn.restype = restype
        fn.argtypes = argtypes
    return lib


class Verdict(ctypes.Structure):
    """params.h verdict_t."""

    _fields_ = [("result", ctypes.c_uint8), ("reason", ctypes.c_char * 96)]


def param_setter(lib: ctypes.CDLL) -> Callable[[str, float], Verdict]:
    """params_set of the firmware host library (simulator.serve.firmware_host) by name, in IDLE, applied: its
    verdict. params_init first."""
    lib.params_set.argtypes = [ctypes.c_uint16, ctypes.c_uint64, ctypes.c_uint8, ctypes.c_bool,
                               ctypes.POINTER(Verdict)]
    lib.params_init()

    def set_param(name: str, value: float) -> Verdict:
        verdict = Verdict()
        bits = struct.unpack("<Q", struct.pack("<d", value))[0]
        lib.params_set(param(name).index, bits, Mode.IDLE, True, ctypes.byref(verdict))
        return verdict

    return set_param


# The filtered-depth learner (shared-z20-bins7-fdepth-term100-vpen1; `hardware` adds planning's early stop and planning
# on growth) reached by PARAM_SET from the agents' defaults, velocity_filter last; shared_model first so that each
# learner on the way fits.
HARDWARE_BY_PARAMS = (("shared_model", 1), ("in_place_sweeps", 1), ("p_explore_start", 0.0), ("term_reward", -100.0),
                      ("vel_penalty", 1.0), ("act_bins", 7), ("z_cells", 20), ("velocity_filter", 1))


class BothAgents:
    """The firmware host library's parameters (params.c) and an in-process virtual agent, set side by side."""

    def __init__(self, lib: ctypes.CDLL) -> None:
        self.lib = lib
        self.set_c = param_setter(lib)  # the firmware's side alone
        _, self.program, _ = in_process_agent()

    def set(self, name: str, value: float) -> tuple[int, bytes]:
        """PARAM_SET on both in IDLE: the (result, reason) they agree on (asserted)."""
        c_verdict = self.set_c(name, value)
        result, reason = self.program.set_param(param(name).index, value)
        assert (c_verdict.result, c_verdict.reason.decode()) == (result, reason), name
        return result, c_verdict.reason

    def c_learner(self) -> LearnerConfigC:
        """The learner_config_t the firmware's parameters make (params_learner_config)."""
        c = LearnerConfigC()
        self.lib.params_learner_config(ctypes.byref(c))
        return c

    def assert_c_is(self, config: LearnerConfig) -> None:
        got, expected = self.c_learner(), c_config(self.lib, config)
        for field_name, *_ in LearnerConfigC._fields_:
            assert getattr(got, field_name) == getattr(expected, field_name), field_name

    def assert_refused_alone(self, name: str, value: float, field_name: str, reason: str) -> None:
        """From the agents' defaults (no shared model) both refuse the shared model's option `name` with one reason,
        and neither stores it: the Python agent's table and LearnerConfig.`field_name` stay 0, C's learner the
        default."""
        assert self.set(name, value) == (AckResult.BAD_VALUE, reason.encode())
        assert self.program.table.value(name) == 0.0 and getattr(self.program.config, field_name) == 0
        self.assert_c_is(LearnerConfig())

    def assert_both_learn(self, config: LearnerConfig) -> None:
        """Both agents' parameters make config (the Python agent's held as f32, its learner to restart), and the C
        learner takes it (learner.c: it fits the host build's arena)."""
        assert asdict(self.program.config) == pytest.approx(asdict(config), rel=1e-7)
        assert self.program.restart_pending  # a learner parameter: the learner restarts
        self.assert_c_is(config)
        self.lib.learner_configure.restype = ctypes.c_bool
        assert self.lib.learner_configure(ctypes.byref(self.c_learner()))


@dataclass
class Recording:
    """One Python learning run, for the C learner to replay: per step (state, action, reward, next state, next raw
    cell); q[0] before any episode, then after each (the last plan's Q, which made the policy); live_q after each
    episode (the Q the model and values give then: a plan's Q, or with a skipped plan the newer model's, as the C
    learner_q renders it); values, policy, sweeps (0: planning on growth skipped the plan) and the stream's state."""

    episodes: list[list[tuple[int, int, float, int, int]]] = field(default_factory=list)
    values: list[np.ndarray] = field(default_factory=list)
    q: list[np.ndarray] = field(default_factory=list)
    live_q: list[np.ndarray] = field(default_factory=list)
    policy: list[np.ndarray] = field(default_factory=list)
    sweeps: list[int] = field(default_factory=list)
    rng_after: list[int] = field(default_factory=list)
    learner: Learner | None = None


def record_python(config: LearnerConfig, plant: str, episodes: int, seed: int) -> Recording:
    """The Python learner learning in the environment (a plant preset) for some episodes."""
    learner = Learner(config, np.random.default_rng(seed))
    env = DivingEnv(preset(plant), config, np.random.default_rng(seed + 1))
    rec = Recording(learner=learner)
    rec.q.append(learner.q_values)
    for _ in range(episodes):
        _, info = env.reset()
        state = info["state"]
        steps = []
        done = False
        while not done:
            action = learner.act(state)
            _, reward, terminated, truncated, info = env.step(action)
            learner.observe(state, action, reward, info["state"], info["cell"])
            steps.append((state, action, reward, info["state"], info["cell"]))
            state = info["state"]
            done = terminated or truncated
        learner.end_episode()
        rec.episodes.append(steps)
        rec.values.append(learner.values)
        rec.q.append(learner.q_values)
        rec.live_q.append(learner.live_q_values())
        rec.policy.append(learner.policy)
        rec.sweeps.append(learner.last_sweeps)
        rec.rng_after.append(int(learner.arrays.rng_state[0]))
    return rec
