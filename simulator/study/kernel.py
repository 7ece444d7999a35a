"""Compiled trial loop of the batch study: the same episode and learner kernels, one trial per thread; a replay
of one trial that also records every step (scripts/replay_trials.py)."""

from __future__ import annotations

import types
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from learning.acting import explore_probability, select_action_kernel
from learning.model import N_ACTIONS, record_transition
from learning.planning import plan_kernel
from learning.shared import allocate_arrays, record_shared
from learning.shared_plan import plan_due, plan_shared_kernel
from learning.spec import KernelSpec
from simulator.parameters import PlantParams
from simulator.plant.episode import (
    E_HELD,
    E_STEPS,
    episode_cell_kernel,
    episode_reset_kernel,
    episode_step_kernel,
    episode_steps,
    new_env_state,
)
from simulator.plant.kernel import MOTOR, Z
from simulator.study.hold import N_ACC, N_HOLD, RECOVERY_HOLDS, hold_add, hold_reset, hold_write, recovery_hold_run

# The fast arithmetic of PlantParams.fast_arithmetic (issue 43), LLVM's fast-math flags that the trial loop may take:
# reciprocals for divisions by a figure the loop holds fixed (arcp), fused multiply-adds (contract), reassociation
# (reassoc) and no signed zeros (nsz). Of a hardware-fast study's CPU arcp alone cut ~8 %, all four ~12 %
# (docs/learners-hold.md s. 4). Not nnan or ninf: the hold's bookkeeping keeps NaN and inf.
FAST_MATH_FLAGS = frozenset({"arcp", "contract", "nsz", "reassoc"})

# Columns of a trial's planning/model counters.
C_EVICTIONS, C_SWEEPS_TOTAL, C_SWEEPS_MAX, C_PLANS = 0, 1, 2, 3
N_COUNTERS = 4


class TrialArrays(NamedTuple):
    """What trials fill: a row per trial for run_trials, one trial's rows for run_trial (numba takes it as a
    named tuple, so the two kernels do not spell the same outputs twice)."""

    durations_s: NDArray[np.float64]  # [episodes] time in the region per episode
    values: NDArray[np.float64]  # [states] value function after the last episode
    policy: NDArray[np.int8]  # [states] greedy policy after the last episode
    counters: NDArray[np.int64]  # [N_COUNTERS] evictions, sweeps in all, most sweeps of one call, planning calls
    hold: NDArray[np.float64]  # [episodes, N_HOLD] hold quality of each successful episode (NaN otherwise)
    # [RECOVERY_HOLDS, N_HOLD] the recovery controller's holds, run after the last episode on the trial's plant
    recovery_hold: NDArray[np.float64]

    @classmethod
    def zeros(cls, trials: tuple[int, ...], episodes: int, states: int) -> TrialArrays:
        """Outputs for `trials` (() for one trial's rows) of `episodes` episodes and `states` learner states."""
        return cls(
            np.zeros((*trials, episodes)), np.zeros((*trials, states)), np.zeros((*trials, states), dtype=np.int8),
            np.zeros((*trials, N_COUNTERS), dtype=np.int64), np.zeros((*trials, episodes, N_HOLD)),
            np.zeros((*trials, RECOVERY_HOLDS, N_HOLD)),
        )

    def row(self, t: int) -> TrialArrays:
        """Trial t's rows of a batch's outputs."""
        return TrialArrays(self.durations_s[t], self.values[t], self.policy[t], self.counters[t], self.hold[t],
                           self.recovery_hold[t])


# Columns of a recorded step: the action taken, the learner's state after it, then the recorded env entries.
S_ACTION, S_STATE, S_ENV = 0, 1, 2


class StepRecord(NamedTuple):
    """What replay_trial records: rows[episode, k] is step k + 1 of the episode (S_* columns, then env[columns]
    after the step, env as simulator/plant/episode.py's E_* lays it out); rows past an episode's end keep what
    the caller put there."""

    columns: NDArray[np.int64]  # [n] the env entries recorded
    rows: NDArray[np.float64]  # [episodes, episode_steps(spec), S_ENV + n]


@njit(cache=True, error_model="numpy", inline="always")
def _record_step(record: StepRecord, episode: int, action: int, state: int, env: NDArray[np.float64]) -> None:
    row = record.rows[episode, int(env[E_STEPS]) - 1]
    row[S_ACTION] = action
    row[S_STATE] = state
    for j in range(record.columns.shape[0]):
        row[S_ENV + j] = env[record.columns[j]]


@njit(cache=True, error_model="numpy", nogil=True)
def _trial(
    learner_stream: NDArray[np.uint64],
    env_stream: NDArray[np.uint64],
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    out: TrialArrays,
    progress: NDArray[np.int64],
    trial: int,
    record: StepRecord | None,
) -> None:
    """The trial loop of run_trial and replay_trial. numba compiles it once per type of record and drops the
    `record is not None` branch when it is None: the study's loop carries no trace of the recording."""
    durations_s, values, policy, counters, hold, recovery_hold = out
    n_states = values.shape[0]
    sparse = lspec.model_form == 1
    shared = lspec.shared_model
    local = (not shared) or lspec.dirichlet_weight > 0.0
    model = allocate_arrays(lspec)
    succ_idx, succ_cnt, reward_sum = model.succ_idx, model.succ_cnt, model.reward_sum
    q = np.zeros((n_states, N_ACTIONS))
    values[:] = 0.0
    if shared:
        plan_shared_kernel(model, values, q, policy, lspec, learner_stream)
    else:
        plan_kernel(succ_idx, succ_cnt, reward_sum, values, q, policy, lspec, learner_stream)
    env = new_env_state(spec)
    acc = np.zeros(N_ACC)
    hold_from = episode_steps(spec) // 2
    for episode in range(durations_s.shape[0]):
        state = episode_reset_kernel(env, target_depth_m, spec, lspec, env_stream)
        p_explore = explore_probability(episode, lspec)
        hold_reset(acc)
        while True:
            action = select_action_kernel(policy, state, p_explore, lspec, learner_stream)
            motor_before = env[MOTOR]
            next_state, reward, terminated, truncated = episode_step_kernel(
                env, action, target_depth_m, spec, lspec, env_stream
            )
            if record is not None:
                _record_step(record, episode, action, next_state, env)
            if env[E_STEPS] > hold_from:
                hold_add(acc, env[Z] - target_depth_m, abs(env[MOTOR] - motor_before), spec.control_period_s)
            if shared and env[E_HELD] == 0.0:
                cell = episode_cell_kernel(env, target_depth_m, spec, lspec)
                if record_shared(model, state, action, cell, lspec):
                    counters[C_EVICTIONS] += 1
            if local and record_transition(
                succ_idx, succ_cnt, reward_sum, state, action, reward, next_state, sparse
            ):
                counters[C_EVICTIONS] += 1
            state = next_state
            if terminated or truncated:
                break
        durations_s[episode] = env[E_STEPS] * spec.control_period_s
        hold_write(acc, hold[episode], truncated)
        if shared:
            if not plan_due(model, lspec):
                progress[trial] = episode + 1
                continue
            sweeps = plan_shared_kernel(model, values, q, policy, lspec, learner_stream)
        else:
            sweeps = plan_kernel(succ_idx, succ_cnt, reward_sum, values, q, policy, lspec, learner_stream)
        counters[C_SWEEPS_TOTAL] += sweeps
        counters[C_SWEEPS_MAX] = max(counters[C_SWEEPS_MAX], sweeps)
        counters[C_PLANS] += 1
        progress[trial] = episode + 1
    # Issue 43: the controller is measured where the learner's last episodes left the plant (its clock, the sensor's
    # drift and noise state), not on a fresh plant at time 0; after the last episode, so nothing above depends on it.
    if recovery_hold.shape[0] > 0:
        recovery_hold_run(env, env_stream, target_depth_m, spec, lspec, recovery_hold)


@njit(cache=True, error_model="numpy", nogil=True)
def run_trial(
    learner_stream: NDArray[np.uint64],
    env_stream: NDArray[np.uint64],
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    out: TrialArrays,
    progress: NDArray[np.int64],
    trial: int,
) -> None:
    """One learning trial: len(out.durations_s) episodes; fills durations, final values, policy and counters."""
    _trial(learner_stream, env_stream, target_depth_m, spec, lspec, out, progress, trial, None)


@njit(cache=True, error_model="numpy", nogil=True)
def replay_trial(
    learner_stream: NDArray[np.uint64],
    env_stream: NDArray[np.uint64],
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    out: TrialArrays,
    record: StepRecord,
) -> None:
    """run_trial with the same streams and the same results, also recording every step into record."""
    _trial(learner_stream, env_stream, target_depth_m, spec, lspec, out, np.zeros(1, np.int64), 0, record)


@njit(cache=True, error_model="numpy", nogil=True, parallel=True)
def run_trials(
    learner_streams: NDArray[np.uint64],
    env_streams: NDArray[np.uint64],
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    out: TrialArrays,
    progress: NDArray[np.int64],
) -> None:
    """All trials in parallel; row t of every output belongs to trial t."""
    for t in prange(out.durations_s.shape[0]):
        rows = TrialArrays(out.durations_s[t], out.values[t], out.policy[t], out.counters[t], out.hold[t],
                           out.recovery_hold[t])
        run_trial(learner_streams[t], env_streams[t], target_depth_m, spec, lspec, rows, progress, t)


def compiled_again(kernel: Any, name: str, fastmath: frozenset[str] = frozenset(), **rebound: Any) -> Any:
    """kernel's Python function compiled again as `name`, with fastmath and its global `rebound` names bound to other
    kernels. Its own name gives it its own cache entry: numba keys a cached kernel by its qualified name and source
    line, not by its flags, so a second build of the same name would load the first's machine code."""
    func = kernel.py_func
    copy = types.FunctionType(func.__code__, {**func.__globals__, **rebound}, name, func.__defaults__,
                              func.__closure__)
    copy.__qualname__ = name
    options = {k: v for k, v in kernel.targetoptions.items() if k != "nopython"}  # njit's own
    if fastmath:
        options["fastmath"] = set(fastmath)
    return njit(cache=True, **options)(copy)


# The same trial loop in fast arithmetic: only _trial takes the flags (the step's kernels are inlined into it); the
# entries around it are the same code calling it. numba compiles a build the first time it runs, so studies that
# never ask for fast arithmetic never compile it.
_trial_fast = compiled_again(_trial, "_trial_fast", FAST_MATH_FLAGS)
_run_trial_fast = compiled_again(run_trial, "_run_trial_fast", _trial=_trial_fast)
_replay_trial_fast = compiled_again(replay_trial, "_replay_trial_fast", _trial=_trial_fast)
_run_trials_fast = compiled_again(run_trials, "_run_trials_fast", run_trial=_run_trial_fast)


class TrialKernels(NamedTuple):
    """The study's compiled entries of one arithmetic: run_trial, run_trials (prange) and replay_trial."""

    run_trial: Callable[..., None]
    run_trials: Callable[..., None]
    replay_trial: Callable[..., None]


_EXACT = TrialKernels(run_trial, run_trials, replay_trial)
_FAST = TrialKernels(_run_trial_fast, _run_trials_fast, _replay_trial_fast)


def trial_kernels(params: PlantParams) -> TrialKernels:
    """The entries a study of params runs: in fast arithmetic if it asks for it (PlantParams.fast_arithmetic)."""
    return _FAST if params.fast_arithmetic else _EXACT
