"""The study runner: same kernels as the Python API, its statistics, its command line."""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from learning import LearnerConfig, learner_preset
from simulator.cli import app
from simulator.parameters import preset
from simulator.study.runner import run_study
from simulator.study.stats import moving_average, per_trial, stable_from
from tests.simulator.python_trial import python_loop_trial

PAPER = preset("paper")


@pytest.mark.slow  # compiles the parallel trial loop on a cold numba cache (~7 s)
def test_the_compiled_study_replays_the_python_api_exactly() -> None:
    config = learner_preset("paper")
    result = run_study(PAPER, config, trials=2, episodes=8, seed=11)
    for trial in range(2):
        expected = python_loop_trial(PAPER, config, 11, trial, 8)
        np.testing.assert_allclose(result.durations_s[trial], expected, atol=1e-9)


def test_literal_exploration_reading_never_learns() -> None:
    # Read literally, Alg. 2 acts against its own policy 90-100 % of the time. On the paper preset's
    # narrow actuator window such dithering survives 300 s by luck in about 2 % of episodes, but the
    # success rate never rises; the fixed reading succeeds in nearly every late episode.
    limit_s = PAPER.episode_limit_s
    literal = run_study(PAPER, LearnerConfig(explore_literal_gt=True), trials=8, episodes=100, seed=0)
    fixed = run_study(PAPER, LearnerConfig(), trials=8, episodes=100, seed=0)
    assert np.mean(literal.durations_s[:, -50:] >= limit_s) < 0.06
    assert np.mean(fixed.durations_s[:, -50:] >= limit_s) > 0.9


def test_same_seed_same_study() -> None:
    a = run_study(PAPER, LearnerConfig(), trials=3, episodes=5, seed=4)
    b = run_study(PAPER, LearnerConfig(), trials=3, episodes=5, seed=4)
    assert np.array_equal(a.durations_s, b.durations_s) and np.array_equal(a.values, b.values)


def test_moving_average_is_trailing_over_50_episodes() -> None:
    durations = np.arange(60, dtype=float)
    alc = moving_average(durations)
    assert np.isnan(alc[48]) and alc[49] == pytest.approx(np.mean(np.arange(50)))
    assert alc[59] == pytest.approx(np.mean(np.arange(10, 60)))


def test_stable_episode_and_per_trial_statistics() -> None:
    curve = np.array([300, 10, 300, 300, 300.0])
    assert stable_from(curve, 300.0) == 2
    assert stable_from(np.array([300, 300, 10.0]), 300.0) is None
    row = np.concatenate([np.full(5, 20.0), [300.0], [50.0], np.full(60, 300.0)])
    stats = per_trial(row[None, :], 300.0)[0]
    assert stats["first_success"] == 5 and stats["last_failure"] == 6 and stats["alc_stable_from"] == 56


def _run_cli(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, ["study", *args])
    return result.exit_code, result.stdout, result.stderr


def test_study_command_writes_curves_summary_and_figures(tmp_path: Path) -> None:
    code, out, _ = _run_cli("--trials", "2", "--episodes", "60", "--out", str(tmp_path), "--json")
    assert code == 0
    summary = json.loads(out)
    assert summary == json.loads((tmp_path / "summary.json").read_text())
    assert summary["memory_bytes"] == 8080 and len(summary["trials"]) == 2
    assert {"median", "best_quarter_q75"} <= set(summary["alc_curves"])
    for name in ("learning_curves.csv", "learning_curves.npz", "fig4_learning_curve.png",
                 "fig5_alc_median_iqr.png", "fig6_value_function.png", "fig7_policy.png"):
        assert (tmp_path / name).stat().st_size > 0
    with np.load(tmp_path / "learning_curves.npz") as data:
        assert data["durations_s"].shape == (2, 60)


@pytest.mark.parametrize(
    "args, message",
    [
        (["--preset", "moon"], "unknown preset"),
        (["--learner", "oracle"], "unknown learner"),
        (["--trials", "0"], "must be positive"),
    ],
)
def test_bad_input_gives_one_line_and_a_nonzero_exit(tmp_path: Path, args: list[str], message: str) -> None:
    code, _, err = _run_cli(*args, "--out", str(tmp_path / "o"))
    assert code != 0 and message in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err


def test_bad_params_file_and_unwritable_folder_are_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("drag_kgpm = 'lots'\n")
    code, _, err = _run_cli("--params", str(bad), "--out", str(tmp_path / "o"))
    assert code != 0 and "drag_kgpm" in err and len(err.strip().splitlines()) == 1
    blocked = tmp_path / "file"
    blocked.write_text("")
    code, _, err = _run_cli("--trials", "1", "--episodes", "1", "--out", str(blocked / "sub"))
    assert code != 0 and "cannot write" in err and len(err.strip().splitlines()) == 1


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_read_only_folder_is_refused(tmp_path: Path) -> None:
    tmp_path.chmod(0o500)
    try:
        code, _, err = _run_cli("--trials", "1", "--episodes", "1", "--out", str(tmp_path / "o"))
    finally:
        tmp_path.chmod(0o700)
    assert code != 0 and "cannot write" in err


def test_params_file_overrides_the_preset(tmp_path: Path) -> None:
    from simulator.parameters import load_params

    good = tmp_path / "p.json"
    good.write_text(json.dumps({"drag_kgpm": 1.7, "use_observer": True}))
    params = load_params(good, PAPER)
    assert params.drag_kgpm == 1.7 and params.use_observer and params.mass_kg == PAPER.mass_kg
