"""`dive log export FOLDER --format minari` (issue 28 item 2): a folder of paper, hardware and C-firmware runs makes
one dataset per environment, named after it, whose recover_environment() builds the plant that made the data.
Real recordings by the real recorder, the real CLI, datasets read back by minari itself."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from groundstation import open_recording
from groundstation.cli.app import app
from groundstation.recording.environments import environment, tidy_number
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.session.events import Received
from protocol import Frame
from protocol import messages as m
from protocol.frame import build_inner
from simulator.parameters import preset, with_overrides
from tests.groundstation.synthetic_agent import generate, play_session

RUNS = {"paper": {"sim_preset": "paper"}, "hardware": {"sim_preset": "hardware"},
        "firmware": {"sim_preset": "paper", "sim_firmware": "c"}}


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("mixed")
    for seed, (name, options) in enumerate(RUNS.items(), 1):
        url = "sim://?" + "&".join(f"{k.removeprefix('sim_')}={v}" for k, v in options.items())
        recorder = Recorder(RecorderConfig(path=folder / f"{name}.mcap"),
                            session_info={"url": url, **options, "sim_seed": str(seed), "sim_speed": "max"})
        recorder.set_parameters({"action_step_deg": 2.0999999046325684, "z_tol_m": 0.10000000149011612,
                                 "z_cells": 10.0, "zdot_cells": 10.0, "target_depth_m": 0.5})
        try:
            play_session(generate(duration_s=60.0, seed=seed), [recorder])
        finally:
            recorder.close()
    # A second paper run whose parameter table came after the file's header (as a run records it when the agent
    # answers late): the same environment, the same dataset.
    late = Recorder(RecorderConfig(path=folder / "paper-late.mcap"),
                    session_info={"url": "sim://?seed=9", "sim_seed": "9"})
    traffic = generate(duration_s=60.0, seed=9)
    traffic = dataclasses.replace(traffic, frames=[_rebooted(r, 0x99) for r in traffic.frames])  # another boot
    try:
        play_session(dataclasses.replace(traffic, frames=traffic.frames[:5], link=[]), [late])
        late.set_parameters({"action_step_deg": 2.0999999046325684, "z_tol_m": 0.10000000149011612,
                             "z_cells": 10.0, "zdot_cells": 10.0, "target_depth_m": 0.5})
        play_session(dataclasses.replace(traffic, frames=traffic.frames[5:]), [late])
    finally:
        late.close()
    return folder


def _rebooted(received: Received, boot_id: int) -> Received:
    frame = received.frame
    if not isinstance(frame.message, m.Hello):
        return received
    hello = m.Hello(**{**frame.message.to_dict(), "boot_id": boot_id})
    inner = build_inner(frame.flags, frame.seq, frame.msg_id, hello.pack())
    return received._replace(frame=Frame(frame.flags, frame.seq, frame.msg_id, hello, inner))


def test_the_environment_key_leaves_out_how_a_run_was_played() -> None:
    header = {"session": [{"url": "sim://?preset=hardware&seed=3", "sim_preset": "hardware", "sim_seed": "3",
                           "sim_drop": "0.1"}], "parameters": [{"z_tol_m": "0.10000000149011612"}]}
    assert environment(header) == {"preset": "hardware", "learner": "paper", "firmware": "python", "z_tol_m": "0.1"}
    assert tidy_number("9.800000190734863") == "9.8" and tidy_number("10.0") == "10"


def test_a_mixed_folder_makes_one_dataset_per_environment(folder: Path, tmp_path: Path,
                                                          monkeypatch: pytest.MonkeyPatch) -> None:
    import minari

    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "datasets"))
    done = CliRunner().invoke(app, ["log", "export", str(folder), "--format", "minari", "--out",
                                    str(tmp_path / "datasets")])
    assert done.exit_code == 0, done.output
    text = " ".join(done.stdout.split())
    assert "3 environments among the recordings (firmware: c, python; preset: hardware, paper)" in text
    ids = {name: f"diving_agent/{folder.name}_{slug}-v0" for name, slug in
           (("paper", "paper_paper_python"), ("hardware", "hardware_paper_python"), ("firmware", "paper_paper_c"))}
    for name, dataset_id in ids.items():
        dataset = minari.load_dataset(dataset_id)
        described = str(dataset.storage.metadata)
        assert "environment" in described and "0.10000000149011612" not in described  # no float32 noise
        assert dataset.spec.env_spec.kwargs["z_tol_m"] == 0.1
        env = dataset.recover_environment()
        # the plant that made the data: the run's preset with the recorded target depth
        assert env.unwrapped.plant == with_overrides(preset(RUNS[name]["sim_preset"]),  # type: ignore[attr-defined]
                                                     {"target_depth_m": 0.5})
        episodes = list(dataset.iterate_episodes())
        runs = [folder / f"{name}.mcap"] + ([folder / "paper-late.mcap"] if name == "paper" else [])
        assert len(episodes) == sum(len(open_recording(run).episodes()) - 1 for run in runs)  # the last is open
        assert episodes and all(env.observation_space.contains(o) for e in episodes for o in e.observations)
        # observations the recovered env itself makes have the recorded ones' shape and bounds
        obs, _ = env.reset(seed=1)
        assert obs.shape == episodes[0].observations[0].shape and np.isfinite(obs).all()

