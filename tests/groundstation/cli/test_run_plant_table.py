"""`dive run --params FILE` with a [plant] table (as `dive fit` writes): the simulator of a sim:// run flies that plant;
a real agent's run says in one line that the table cannot apply and sets the file's agent parameters all the same."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation import open_recording
from groundstation.cli.app import app
from tests.groundstation.fake_agent import FakeAgent

RHO_G = 1000.0 * 9.81  # the agent's depth from pressure (protocol SPEC: fresh water)
SURFACE_PA = 95000.0  # far from the preset's 101325 Pa: a run that dropped the table cannot land near it


def _plant_file(path: Path) -> Path:
    path.write_text(f"target_depth_m = 0.5\n\n[plant]\nsurface_pressure_pa = {SURFACE_PA}\npressure_noise_pa = 1.0\n")
    return path


@pytest.mark.slow
def test_a_sim_run_flies_the_files_plant_and_sets_its_agent_parameters(tmp_path: Path) -> None:
    out = tmp_path / "run.mcap"
    done = CliRunner().invoke(app, ["run", "sim://?speed=max&seed=3&preset=hardware", "--episodes", "1",
                                    "--params", str(_plant_file(tmp_path / "fitted.toml")), "--out", str(out),
                                    "--viewer", "none"], env={"COLUMNS": "200"})
    assert done.exit_code == 0, done.stderr
    assert "cannot apply" not in done.stderr
    recording = open_recording(out)
    samples = recording.samples()
    assert len(samples) > 50
    # The agent takes P0 at boot (at the surface): every reading less its depth's water column is that P0.
    surface_pa = samples["pressure_pa"] - RHO_G * samples["depth_m"]
    assert abs(float(np.median(surface_pa)) - SURFACE_PA) < 10.0
    starts = recording.table("/agent/EPISODE_START")
    assert len(starts) >= 1 and starts["target_depth_m"][0] == pytest.approx(0.5)


def test_a_real_agents_run_warns_in_one_line_and_sets_the_agent_parameters(tmp_path: Path) -> None:
    agent = FakeAgent()
    try:
        done = CliRunner().invoke(app, ["run", agent.url, "--episodes", "1", "--params",
                                        str(_plant_file(tmp_path / "fitted.toml")), "--out", str(tmp_path / "r")],
                                  env={"COLUMNS": "200"})
    finally:
        agent.close()
    assert done.exit_code == 0, done.stderr
    warnings = [line for line in done.stderr.splitlines() if "[plant]" in line]
    assert len(warnings) == 1 and "cannot apply to tcp://" in warnings[0], done.stderr
    assert agent.params["target_depth_m"][1] == pytest.approx(0.5)
