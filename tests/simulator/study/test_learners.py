"""The new learners in the study, the comparison run, honest statistics and sweeps (locally and on Dask)."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from learning import learner_preset
from simulator.cli import app
from simulator.parameters import preset
from simulator.study.runner import run_study
from simulator.study.stats import summarise
from simulator.study.sweep import load_sweep, run_sweep
from tests.simulator.python_trial import python_loop_trial


@pytest.mark.slow  # compiles the parallel trial loop on a cold numba cache
@pytest.mark.parametrize("preset_name, learner", [("paper", "shared-dirichlet"), ("hardware", "shared-bins13-diff4"),
                                                  ("hardware", "shared-z20-bins7-diff8-term100-vpen1")])
def test_the_compiled_study_replays_the_python_api_for_the_shared_learners(preset_name: str, learner: str) -> None:
    params, config = preset(preset_name), learner_preset(learner, ties_per_step=True)
    result = run_study(params, config, trials=2, episodes=6, seed=5)
    for trial in range(2):
        np.testing.assert_allclose(result.durations_s[trial], python_loop_trial(params, config, 5, trial, 6),
                                   atol=1e-9)


def test_never_stable_trials_are_censored_not_dropped() -> None:
    # Two trials stable from episode 49, two never: the median is not 49 but "never".
    good = np.full(100, 300.0)
    bad = np.concatenate([np.full(99, 300.0), [10.0]])
    stats = summarise(np.stack([good, good, bad, bad, bad]), 300.0, seed=0)["across_trials"]["alc_stable_from"]
    assert stats["fraction_never"] == pytest.approx(0.6) and stats["median"] is None
    assert stats["q25"] == 49.0 and stats["censored_at"] == 100


def _run_cli(*args: str) -> tuple[int, str, str]:
    result = CliRunner().invoke(app, ["study", *args])
    return result.exit_code, result.stdout, result.stderr


def test_compare_runs_learners_on_the_same_seeds_with_ratios(tmp_path: Path) -> None:
    code, out, err = _run_cli("--compare", "paper,shared,hardware/shared-bins13-diff4", "--trials", "3",
                              "--episodes", "55", "--out", str(tmp_path), "--json")
    assert code == 0, err
    rows = json.loads(out)
    # The hardware preset runs in the simulation's region and the experiment's.
    assert [r["label"] for r in rows] == ["paper/paper", "paper/shared", "hardware/shared-bins13-diff4@0.1/0.04",
                                          "hardware/shared-bins13-diff4@0.15/0.03"]
    assert rows[1]["reference"] == "paper/paper" and rows[3]["reference"] == rows[2]["label"]
    assert rows[1]["memory_bytes"] == 1204 and rows[2]["memory_bytes"] == 15604
    assert (tmp_path / "compare_fig5_alc.png").stat().st_size > 0
    with (tmp_path / "compare.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 4
    summary = json.loads((tmp_path / "paper_shared" / "summary.json").read_text())
    assert summary["learner_config"]["shared_model"] is True and len(summary["trials"]) == 3


def test_learner_options_and_region_reach_the_study(tmp_path: Path) -> None:
    code, out, err = _run_cli("--preset", "hardware", "--learner", "shared", "--z-tol", "0.15", "--zdot-tol",
                              "0.03", "--exploration", "bonus", "--ties", "per-step", "--actuator-bins", "3",
                              "--velocity-diff", "4", "--max-sweeps", "5", "--seeds", "0-1", "--trials", "1",
                              "--episodes", "3", "--out", str(tmp_path), "--json")
    assert code == 0, err
    summary = json.loads(out)
    config = summary["learner_config"]
    assert (config["z_tol_m"], config["zdot_tol_mps"], config["count_bonus"], config["ties_per_step"]) == (
        0.15, 0.03, 0.5, True)
    assert (config["actuator_bins"], config["velocity_diff_steps"], config["max_sweeps"]) == (3, 4, 5)
    assert summary["seeds"] == [0, 1] and len(summary["trials"]) == 2
    assert summary["model"]["planning_sweeps_per_call_max"] <= 5


def test_bad_sweep_file_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "s.toml"
    bad.write_text('learners = ["paper"]\n[grid]\nwarp_drive = [1]\n')
    code, _, err = _run_cli("--sweep", str(bad), "--out", str(tmp_path / "o"))
    assert code != 0 and "warp_drive" in err and len(err.strip().splitlines()) == 1


@pytest.mark.slow  # starts a Dask LocalCluster
def test_a_sweep_gives_the_same_table_here_and_on_a_dask_cluster(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('trials = 2\nepisodes = 52\nseeds = [0, 1]\nlearners = ["shared"]\n'
                     '[grid]\nactuator_bins = [1, 3]\n')
    tasks = load_sweep(sweep)
    assert len(tasks) == 4
    local = run_sweep(tasks)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:  # in-process transport, no ports
        remote = run_sweep(tasks, cluster=cluster.scheduler_address)
    strip = [{k: v for k, v in r.items() if k != "wall_s"} for r in local]
    assert strip == [{k: v for k, v in r.items() if k != "wall_s"} for r in remote]
    assert {r["param_actuator_bins"] for r in local} == {1, 3} and {r["seed"] for r in local} == {0, 1}
    code, _, err = _run_cli("--sweep", str(sweep), "--out", str(tmp_path / "o"))
    assert code == 0, err
    assert (tmp_path / "o" / "sweep.png").stat().st_size > 0
    with (tmp_path / "o" / "sweep.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 4


def test_an_unreachable_scheduler_is_a_failure_in_one_line_not_bad_usage(tmp_path: Path) -> None:
    import socket

    with socket.socket() as probe:  # a port nobody listens on once this closes
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('trials = 1\nepisodes = 2\nseeds = [0]\nlearners = ["shared"]\n[grid]\nactuator_bins = [1]\n')
    code, _, err = _run_cli("--sweep", str(sweep), "--out", str(tmp_path / "o"), "--cluster",
                            f"tcp://127.0.0.1:{port}")
    lines = err.strip().splitlines()
    assert code == 1 and len(lines) == 1 and f"cannot reach the Dask scheduler at tcp://127.0.0.1:{port}" in lines[0]
