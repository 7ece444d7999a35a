"""`dive log export --format npz` (issue 28 item 2): any --out name, a folder made when asked, no temporary file
left, and the observation columns of DivingAgent-v0 and the Minari export. A real recording, the real CLI."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.recording.minari_export import episode_buffers
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.recording.tables import open_recording
from tests.groundstation.synthetic_agent import generate, play_session


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("npz") / "run.mcap"
    recorder = Recorder(RecorderConfig(path=path))
    recorder.set_parameters({"action_step_deg": 2.0, "z_cells": 10.0, "zdot_cells": 10.0})
    try:
        play_session(generate(duration_s=120.0), [recorder])
    finally:
        recorder.close()
    return path


def test_any_out_name_and_a_new_folder(recording: Path, tmp_path: Path) -> None:
    runner = CliRunner()
    named = runner.invoke(app, ["log", "export", str(recording), "--format", "npz", "--out", str(tmp_path / "NAME")])
    assert named.exit_code == 0, named.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["NAME"]  # exactly that name, no hidden temporary beside it
    with np.load(tmp_path / "NAME") as data:
        assert len(data["action"]) > 100
    folder = tmp_path / "new" / "dir"
    made = runner.invoke(app, ["log", "export", str(recording), "--format", "npz", "--out", f"{folder}/"])
    assert made.exit_code == 0, made.output
    assert sorted(p.name for p in folder.iterdir()) == ["run.npz"]


def test_observations_are_the_minari_ones(recording: Path, tmp_path: Path) -> None:
    target = tmp_path / "t.npz"
    assert CliRunner().invoke(app, ["log", "export", str(recording), "--format", "npz", "--out",
                                    str(target)]).exit_code == 0
    buffers, _ = episode_buffers(open_recording(recording), lambda **kw: kw)
    with np.load(target) as data:
        assert data["observation"].shape[1] == data["next_observation"].shape[1] == 3
        episodes: dict[int, Any] = {}
        for b in buffers:
            episodes[len(episodes) + 1] = b
        for number, buffer in episodes.items():
            mine = data["episode"] == number
            observed = buffer["observations"]
            assert np.allclose(data["observation"][mine], observed[:-1], atol=1e-6)
            assert np.allclose(data["next_observation"][mine], observed[1:], atol=1e-6)
            assert (data["action"][mine] == buffer["actions"]).all()
