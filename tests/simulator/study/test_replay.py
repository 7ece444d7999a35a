"""replay_trial: the study's own trial to the bit, with every step recorded (what scripts/replay_trials.py reads)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from learning import learner_preset, n_states
from learning.config import kernel_spec
from simulator.parameters import kernel_params, preset
from simulator.plant.episode import E_STEPS, E_VEL_EST, episode_steps
from simulator.study.kernel import S_ACTION, S_ENV, S_STATE, StepRecord, TrialArrays, trial_kernels
from simulator.study.runner import run_study, trial_streams

TRIALS, EPISODES, SEED = 2, 12, 3


# hardware-fast: its trial loop in fast arithmetic (PlantParams.fast_arithmetic), which a replay must run as well.
@pytest.mark.parametrize("preset_name", ["hardware", "hardware-fast"])
def test_a_replayed_trial_is_the_study_trial_with_each_step_recorded(preset_name: str) -> None:
    params = preset(preset_name)
    config = learner_preset("shared", p_explore_start=0.2)  # exploring: a replay must draw as the study does
    spec, lspec = kernel_params(params), kernel_spec(config)
    study = run_study(params, config, TRIALS, EPISODES, SEED)
    terminal, limit = n_states(config) - 1, episode_steps(spec)
    for t in range(TRIALS):
        out = TrialArrays.zeros((), EPISODES, n_states(config))
        record = StepRecord(np.array([E_STEPS, E_VEL_EST]), np.full((EPISODES, limit, S_ENV + 2), np.nan))
        trial_kernels(params).replay_trial(*trial_streams(SEED, t), params.target_depth_m, spec, lspec, out, record)
        for replayed, studied in zip(out, (study.durations_s, study.values, study.policy, study.counters,
                                           study.hold, study.recovery_hold), strict=True):
            assert np.array_equal(replayed, studied[t], equal_nan=True)
        for episode, duration_s in enumerate(out.durations_s):
            n = round(duration_s / params.control_period_s)
            rows = record.rows[episode]
            assert np.array_equal(rows[:n, S_ENV], np.arange(1, n + 1))  # row k: the env after step k + 1
            assert np.isnan(rows[n:]).all()  # nothing past the episode's end
            assert np.isin(rows[:n, S_ACTION], (0.0, 1.0)).all() and np.isfinite(rows[:n, S_ENV + 1]).all()
            states = rows[:n, S_STATE]
            assert (states[:-1] != terminal).all()  # only the last step may reach the terminal state
            assert states[-1] == terminal or n == limit  # and an episode ends there or at its time limit


def test_a_fast_arithmetic_study_runs_its_own_build_on_every_path() -> None:
    """The batch (prange) and the one-plant-per-trial path (a plant family's) run the same fast build: the same bits,
    and not the exact build's (whose plant ends its trials on other last bits)."""
    params = preset("hardware-fast")
    config = learner_preset("hardware-fastplan")
    batch = run_study(params, config, TRIALS, EPISODES, SEED)
    per_plant = run_study(params, config, TRIALS, EPISODES, SEED, plants=[params] * TRIALS)
    exact = run_study(dataclasses.replace(params, fast_arithmetic=False), config, TRIALS, EPISODES, SEED)
    outputs = ("durations_s", "values", "policy", "counters", "hold", "recovery_hold")
    for name in outputs:
        assert np.array_equal(getattr(batch, name), getattr(per_plant, name), equal_nan=True), name
    assert any(not np.array_equal(getattr(batch, name), getattr(exact, name), equal_nan=True) for name in outputs)
