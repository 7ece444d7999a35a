"""Issue 43's two screened options (docs/learners-hold.md, "A hold and a re-centred window"): a hold (a step of 0
while the depth error and velocity the learner sees are inside LearnerConfig.hold_depth_m / hold_speed_mps) and the
action window re-centred on the neutral the learner finds (LearnerConfig.neutral_gain), in the environment the study
runs."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from learning.errors import LearnerConfigError
from learning.presets import learner_preset
from simulator.agent.mission import MissionConfig
from simulator.agent.onboard import PythonAgent
from simulator.gym.task import DivingEnv
from simulator.parameters import preset
from simulator.plant.episode import E_FILT_Z, E_NEUTRAL, E_REC_AVG
from simulator.study.runner import run_study


def test_a_step_inside_the_hold_leaves_the_command_still() -> None:
    params = preset("hardware")
    config = learner_preset("fine21-rev14", hold_depth_m=0.003, hold_speed_mps=0.004)
    env = DivingEnv(params, config)
    obs, info = env.reset(seed=5)
    rng = np.random.default_rng(5)
    moved: dict[bool, list[float]] = {True: [], False: []}
    for _ in range(6000):
        error_m = env._env[E_FILT_Z] - params.target_depth_m  # the learner's depth: its filter's (fdepth)
        held = abs(error_m) < config.hold_depth_m and abs(obs[1]) < config.hold_speed_mps
        # Mostly towards the target, so that the hold is reached; sometimes the other way.
        toward = 1 if error_m > 0.0 else 0
        action = toward if rng.random() < 0.8 else 1 - toward
        before = info["alpha_cmd_deg"]
        obs, _, terminated, truncated, info = env.step(action)
        if abs(obs[2]) < params.action_window_deg - 1e-9:  # not clamped by the window
            moved[held].append(abs(info["alpha_cmd_deg"] - before))
        if terminated or truncated:
            obs, info = env.reset()
    assert len(moved[True]) > 20 and max(moved[True]) == 0.0
    assert len(moved[False]) > 20 and min(moved[False]) > 0.0


def test_the_window_is_centred_on_the_neutral_the_learner_finds() -> None:
    """With neutral_gain the learner's neutral follows its own command (by that gain) at each step inside a quarter
    of the region, and not elsewhere; a hand-over then centres the window, and starts the command, on it instead of
    on the controller's average (which the tank family hands over up to 3 deg off neutral, start_trim_error_deg)."""
    params = replace(preset("hardware"), start_trim_error_deg=3.0)
    config = learner_preset("fine21-rev14", neutral_gain=0.01)
    env = DivingEnv(params, config)
    obs, info = env.reset(seed=7)
    assert env._env[E_NEUTRAL] == info["alpha_cmd_deg"] - obs[2]  # the first: the controller's hand-over
    rng = np.random.default_rng(7)
    updated = {True: 0, False: 0}
    for _ in range(3000):
        error_m = env._env[E_FILT_Z] - params.target_depth_m
        inside = abs(error_m) < 0.25 * config.z_tol_m and abs(obs[1]) < 0.25 * config.zdot_tol_mps
        before = env._env[E_NEUTRAL]
        obs, _, terminated, truncated, info = env.step(int(rng.integers(2)))
        expected = before + config.neutral_gain * (info["alpha_cmd_deg"] - before) if inside else before
        assert env._env[E_NEUTRAL] == pytest.approx(expected, abs=1e-12)
        updated[inside] += 1
        if terminated or truncated:
            obs, info = env.reset()
    assert min(updated.values()) > 20, updated
    found = env._env[E_REC_AVG] + params.start_trim_error_deg + 2.0  # a neutral 2 deg off the controller's
    env._env[E_NEUTRAL] = found
    obs, info = env.reset()
    assert info["alpha_cmd_deg"] == found and obs[2] == 0.0  # command and window centre on it


def test_the_agents_refuse_them() -> None:
    """The agents have no parameter for either option: a virtual agent given one refuses it rather than ignore it."""
    for option in ({"hold_depth_m": 0.003, "hold_speed_mps": 0.004}, {"hold_lash_deg": 0.5}, {"neutral_gain": 0.01}):
        with pytest.raises(LearnerConfigError, match="study options"):
            PythonAgent(preset("hardware"), learner_preset("fine21-rev14", **option), MissionConfig(),
                        np.random.default_rng(1), lambda wire: None, node_id=6, key=None)


def test_a_held_step_teaches_the_model_nothing() -> None:
    """The shared model's types assume every action moves the gear: held steps are not counted. With the hold over the
    whole region every step is held, so the learner's values after several episodes are those it planned from an
    empty model; without the hold they are not."""
    params = preset("hardware")
    everywhere = learner_preset("fine21-rev14", hold_depth_m=1.0, hold_speed_mps=1.0)
    untaught = run_study(params, everywhere, 1, 1, seed=3, threads=1).values
    held = run_study(params, everywhere, 1, 4, seed=3, threads=1).values
    taught = run_study(params, learner_preset("fine21-rev14"), 1, 4, seed=3, threads=1).values
    np.testing.assert_array_equal(held, untaught)
    assert not np.array_equal(taught, untaught)


def test_a_hold_goes_to_the_neutral_past_the_lash_and_stays() -> None:
    """With neutral_gain, entering a hold moves the command to the neutral found plus hold_lash_deg in the direction
    of that move (a gear's output trails its motor by half the lash); the held steps after it leave it there."""
    params = preset("hardware")
    config = learner_preset("fine21-rev14", neutral_gain=0.01, hold_depth_m=0.003, hold_speed_mps=0.004,
                            hold_lash_deg=0.5)
    env = DivingEnv(params, config)
    obs, info = env.reset(seed=5)
    rng = np.random.default_rng(5)
    entered, stayed, was_held = 0, 0, False
    for _ in range(6000):
        error_m = env._env[E_FILT_Z] - params.target_depth_m
        held = abs(error_m) < config.hold_depth_m and abs(obs[1]) < config.hold_speed_mps
        toward = 1 if error_m > 0.0 else 0
        action = toward if rng.random() < 0.8 else 1 - toward
        before, neutral = info["alpha_cmd_deg"], env._env[E_NEUTRAL]
        obs, _, terminated, truncated, info = env.step(action)
        if held and abs(obs[2]) < params.action_window_deg - 1e-9:
            if was_held:
                assert info["alpha_cmd_deg"] == before
                stayed += 1
            elif neutral != before:
                overshoot = config.hold_lash_deg if neutral > before else -config.hold_lash_deg
                assert info["alpha_cmd_deg"] == pytest.approx(neutral + overshoot, abs=1e-12)
                entered += 1
        was_held = held
        if terminated or truncated:
            obs, info = env.reset()
            was_held = False
    assert entered >= 5 and stayed > 10, (entered, stayed)
