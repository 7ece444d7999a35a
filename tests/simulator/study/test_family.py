"""Plant families: each trial draws its own plant from its seed, reproducibly; bad files are one line."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from learning import learner_preset
from simulator.cli import app
from simulator.errors import ParamsError
from simulator.parameters import preset
from simulator.study.family import load_family
from simulator.study.runner import run_study

TANK = Path(__file__).resolve().parents[3] / "docs" / "families" / "tank.toml"


def test_trials_draw_different_plants_and_a_seed_draws_the_same_one() -> None:
    base = preset("hardware")
    family = load_family(TANK, base)
    a, b = family.draw(base, 0, 0), family.draw(base, 0, 1)
    assert a != b and a.backlash_deg != b.backlash_deg
    assert family.draw(base, 0, 0) == a and load_family(TANK, base).draw(base, 0, 0) == a
    assert family.draw(base, 1, 0) != a
    draws = [family.draw(base, 3, t) for t in range(200)]
    lags = [p.pressure_lag_s for p in draws]
    assert 0.0 <= min(lags) < 0.02 and 0.18 < max(lags) <= 0.2  # spans the documented range
    assert {p.mass_kg for p in draws} == {base.mass_kg}  # what the file does not name stays


def test_a_family_of_one_plant_runs_the_plain_study_exactly(tmp_path: Path) -> None:
    path = tmp_path / "fixed.toml"
    path.write_text("[drag_kgpm]\nvalue = 1.0\n")
    params = preset("paper")
    family = load_family(path, params)
    config = learner_preset("paper")
    plants = [family.draw(params, k, t) for k in (4, 5) for t in range(2)]
    plain = run_study(params, config, 2, 6, seeds=[4, 5])
    drawn = run_study(params, config, 2, 6, seeds=[4, 5], plants=plants)
    np.testing.assert_array_equal(plain.durations_s, drawn.durations_s)
    np.testing.assert_array_equal(plain.values, drawn.values)


@pytest.mark.parametrize(
    "text, message",
    [
        ("[moon_kg]\nuniform = [0, 1]\n", "not a numeric plant parameter"),
        ("[drag_kgpm]\nuniform = [2, 1]\n", "low <= high"),
        ("[drag_kgpm]\nnormal = [1]\n", "takes 2"),
        ("[drag_kgpm]\nuniform = [0, 1]\nnormal = [1, 1]\n", "exactly one"),
        ("[backlash_deg]\nuniform = [-3, -1]\n", "unusable plant"),
        ("drag_kgpm = 3\n", "must be a table"),
    ],
)
def test_bad_family_files_are_refused(tmp_path: Path, text: str, message: str) -> None:
    path = tmp_path / "f.toml"
    path.write_text(text)
    with pytest.raises(ParamsError, match=message):
        load_family(path, preset("hardware"))


def test_study_command_records_each_trials_plant(tmp_path: Path) -> None:
    result = CliRunner().invoke(app, ["study", "--plant-family", str(TANK), "--trials", "2", "--episodes", "3",
                                      "--out", str(tmp_path), "--json"])
    assert result.exit_code == 0, result.stderr
    summary = json.loads(result.stdout)
    assert summary["plant_family"]["spreads"]["backlash_deg"] == "U(0, 2)"
    plants = summary["trial_plants"]
    assert len(plants) == 2 and plants[0] != plants[1]
    bad = CliRunner().invoke(app, ["study", "--plant-family", str(tmp_path / "none.toml"), "--out", str(tmp_path)])
    assert bad.exit_code != 0 and "cannot read" in bad.stderr and len(bad.stderr.strip().splitlines()) == 1


def test_a_sweep_over_plant_files_and_a_family(tmp_path: Path) -> None:
    from simulator.study.sweep import load_sweep, run_sweep

    (tmp_path / "noisy.toml").write_text("pressure_noise_pa = 13.0\n")
    (tmp_path / "fam.toml").write_text("[backlash_deg]\nuniform = [0.0, 2.0]\n")
    sweep = tmp_path / "sweep.toml"
    sweep.write_text('trials = 2\nepisodes = 3\npresets = ["hardware"]\nlearners = ["hardware"]\n'
                     'plants = ["", "noisy.toml"]\nplant_family = "fam.toml"\n')
    tasks = load_sweep(sweep)
    assert [Path(t["plant"]).name if t["plant"] else "" for t in tasks] == ["", "noisy.toml"]
    rows = run_sweep(tasks)
    assert [(r["plant"], r["plant_family"]) for r in rows] == [("", "fam"), ("noisy", "fam")]
    assert all(0.0 <= r["never_stable_ci95_low"] <= r["never_stable_ci95_high"] <= 1.0 for r in rows)
    sweep.write_text('learners = ["hardware"]\nplants = ["missing.toml"]\n')
    with pytest.raises(ParamsError, match="cannot read"):
        load_sweep(sweep)
