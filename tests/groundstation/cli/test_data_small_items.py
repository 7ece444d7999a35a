"""Issue 28's small items: presets refused before the simulator starts, keygen names `dive sim`, parameters in
`log info --json` without float32 noise, ids in hex; the real `dive` process and real recordings."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from groundstation.cli.validate import PLANT_PRESETS
from groundstation.recording.recorder import Recorder, RecorderConfig
from simulator.parameters import preset_names
from tests.groundstation.recording_fixtures import hello, received, sample
from tests.reliability.recordings import dive


def test_the_ground_stations_preset_names_are_the_simulators() -> None:
    assert sorted(PLANT_PRESETS) == preset_names()


@pytest.mark.parametrize(("option", "value", "said"), [("--preset", "hardwar", "unknown --preset 'hardwar'"),
                                                       ("--learner", "foo", "unknown --learner 'foo'")])
def test_a_wrong_preset_is_bad_usage_before_the_simulator_starts(option: str, value: str, said: str,
                                                                  tmp_path: Path) -> None:
    done = dive("run", option, value, "--episodes", "1", "--viewer", "none", "--out", str(tmp_path / "r.mcap"),
                env={"PATH": "", "DIVE_RUNTIME_DIR": str(tmp_path / "rt"), "HOME": str(tmp_path)}, timeout_s=60)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1 and said in lines[0] and "choose one of" in lines[0], done.stderr
    assert "connecting" not in done.stdout + done.stderr and not (tmp_path / "r.mcap").exists()


def test_keygen_names_dive_sim(tmp_path: Path) -> None:
    done = dive("keygen", "--out", str(tmp_path / "k.key"))
    assert done.returncode == 0, done.stderr
    assert "agent: dive sim --key-file" in done.stderr and "python -m simulator" not in done.stderr


def test_log_info_json_has_no_float32_noise_and_ids_in_hex(tmp_path: Path) -> None:
    path = tmp_path / "r.mcap"
    recorder = Recorder(RecorderConfig(path=path))
    recorder.set_parameters({"gravity_mps2": 9.800000190734863, "z_tol_m": 0.10000000149011612, "z_cells": 10.0})
    recorder.on_received(received(hello(0x2A), 0))
    recorder.on_received(received(sample(0), 1))
    recorder.close()
    done = dive("log", "info", str(path), "--json")
    assert done.returncode == 0, done.stderr
    summary = json.loads(done.stdout)
    assert summary["parameters"] == {"gravity_mps2": 9.8, "z_tol_m": 0.1, "z_cells": 10}
    assert "9.800000190734863" not in done.stdout
    assert summary["agent"]["boot_id"] == "0000002a" and summary["agent"]["node_id"] == "00000007"
    assert summary["boots"][0]["boot_id"] == "0000002a"


def test_a_replay_window_past_the_end_is_one_line_and_writes_nothing(tmp_path: Path) -> None:
    from tests.groundstation.synthetic_agent import generate, play_session

    path = tmp_path / "r.mcap"
    recorder = Recorder(RecorderConfig(path=path))
    recorder.set_parameters({"z_cells": 10.0, "zdot_cells": 10.0})  # the header's table: setup items, not frames
    try:
        play_session(generate(duration_s=120.0), [recorder])
    finally:
        recorder.close()
    for window in (["--from", "2h"], ["--from", "e500", "--to", "e600"]):
        rrd = tmp_path / "w.rrd"
        done = dive("replay", str(path), "--rrd", str(rrd), *window)
        lines = done.stderr.strip().splitlines()
        assert done.returncode == 1 and len(lines) == 1, done.stderr
        assert f"the window {' '.join(window)} holds no agent frames" in lines[0], lines
        assert "the recording spans 120 s of agent time" in lines[0], lines
        assert not rrd.exists()
    inside = dive("replay", str(path), "--rrd", str(tmp_path / "in.rrd"), "--from", "60s")
    assert inside.returncode == 0 and (tmp_path / "in.rrd").stat().st_size > 0, inside.stderr
