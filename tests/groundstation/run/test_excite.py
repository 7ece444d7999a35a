"""`dive fit --excite`: the identification manoeuvre flown on the virtual agent, recorded, and handed to the fit."""

from __future__ import annotations

import json
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from groundstation.errors import GroundStationError
from groundstation.recording.recorder import RecorderConfig
from groundstation.recording.tables import open_recording
from groundstation.run.excite import ExciteConfig, excite
from protocol import Mode

pytestmark = pytest.mark.slow
SIM = "sim://?speed=max&seed=4&preset=hardware"


def _dive(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "groundstation.cli.app", *args], capture_output=True, text=True,
                          timeout=240, cwd=cwd)


def test_the_manoeuvre_is_recorded_and_fitted(tmp_path: Path) -> None:
    done = _dive("fit", "--excite", SIM, "--depths", "0.3,0.6,0.4", "--hold", "25", "--json", "--out", "plant.toml",
                 cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    recordings = sorted((tmp_path / "recordings").glob("*.mcap"))
    assert len(recordings) == 1
    samples = open_recording(recordings[0]).samples()
    hovering = samples[samples["mode"] == Mode.HOVER]
    assert len(hovering) > 25 * 3 * 40 * 0.9  # three holds of 25 s at 40 Hz
    # Then the reversals (12 flips of 3 s): the commanded actuator jumps one way and the other, flip after flip.
    flips = hovering[hovering["t_us"] > hovering["t_us"].max() - 36e6]["actuator_cmd_deg"].astype(np.float64)
    jumps = np.diff(flips)[np.abs(np.diff(flips)) > 2.0]
    # at least two reversals of the command (how many of the 12 jumps exceed 2 deg in the window varies with load)
    assert np.count_nonzero(np.diff(np.sign(jumps))) >= 2, jumps
    assert hovering["depth_m"].max() > 0.55 and samples["mode"][-1] in (Mode.SURFACING, Mode.IDLE)
    fitted = json.loads(done.stdout)
    assert fitted["recordings"] == [str(recordings[0].resolve())] or fitted["recordings"][0].endswith(
        recordings[0].name)
    # The hardware preset's plant: steps between hover depths identify the added mass and the neutral angle.
    added_mass = fitted["estimates"]["added_mass_kg"]
    assert added_mass["identified"] and abs(added_mass["value"] - 0.10) <= 2 * added_mass["half_width_95"]
    assert fitted["estimates"]["neutral_angle_deg"]["identified"]
    # dive log info shows how far the recording is from a fitted plant: here, its own, so about the noise.
    info = _dive("log", "info", str(recordings[0]), "--plant", "plant.toml", "--json", cwd=tmp_path)
    assert info.returncode == 0, info.stderr
    residual = json.loads(info.stdout)["plant_residual"]
    assert residual["windows"] >= 3 and residual["residual_rms_m"] <= 1.5 * residual["noise_rms_m"]
    # A changed robot (here: 3 deg of neutral angle, as a leak would shift it) shows as a growing residual.
    figures = tomllib.loads((tmp_path / "plant.toml").read_text())["plant"]
    figures["trim_error_fraction"] += 3.0 / 3414.7  # d(neutral angle)/d(trim) = alpha_max m / (rho dV) deg
    changed = tmp_path / "changed.toml"
    changed.write_text("[plant]\n" + "".join(f"{name} = {value!r}\n" for name, value in figures.items()))
    far = _dive("log", "info", str(recordings[0]), "--plant", str(changed), cwd=tmp_path)
    assert far.returncode == 0, far.stderr
    line = next(x for x in far.stdout.splitlines() if x.startswith("fit residual against"))
    assert float(line.split("; ")[1].split("x the plant")[0]) > 5.0, line
    missing = _dive("log", "info", str(recordings[0]), "--plant", "absent.toml", cwd=tmp_path)
    assert missing.returncode == 1 and "no such plant file" in missing.stderr


def test_the_reversals_flip_the_hover_depth_at_each_amplitude_after_the_depths() -> None:
    config = ExciteConfig(depths_m=(0.3, 0.6), hold_s=10.0, reversals_m=(0.02, 0.1), reversal_hold_s=2.0)
    assert config.steps() == [(0.3, 10.0), (0.6, 10.0), (0.62, 2.0), (0.6, 2.0), (0.62, 2.0), (0.6, 2.0),
                              (0.7, 2.0), (0.6, 2.0), (0.7, 2.0), (0.6, 2.0)]
    assert config.max_dive_s == 3.0 * (20.0 + 16.0) + 60.0
    assert ExciteConfig(depths_m=(0.3,), reversals_m=()).steps() == [(0.3, 30.0)]


@pytest.mark.parametrize(("args", "says"), [
    (("--reversals", "0.05,x"), "take numbers"),
    (("--reversals", "0.3", "--depths", "0.3,0.8"), "outside"),  # 0.8 + 0.3 m beyond --max-depth 1.0
    (("--reversal-hold", "0"), "--reversal-hold must be positive"),
    (("--reversals", "-0.05"), "no reversal"),
])
def test_a_bad_reversal_is_refused_in_one_line_before_connecting(tmp_path: Path, args: tuple[str, ...],
                                                                  says: str) -> None:
    done = _dive("fit", "--excite", "tcp://127.0.0.1:9", *args, cwd=tmp_path)
    assert done.returncode == 2 and "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and says in lines[0], done.stderr
    assert not (tmp_path / "recordings").exists()


def test_a_depth_beyond_the_limit_is_refused_before_connecting(tmp_path: Path) -> None:
    done = _dive("fit", "--excite", "tcp://127.0.0.1:9", "--depths", "0.3,1.5", "--max-depth", "1.0", cwd=tmp_path)
    assert done.returncode == 2
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "outside" in lines[0] and "Traceback" not in done.stderr
    assert not (tmp_path / "recordings").exists()


def test_a_lost_link_stops_the_manoeuvre_and_keeps_the_recording(tmp_path: Path) -> None:
    # Speed 20, not max: the virtual agent never drops a connection younger than a second of wall time.
    config = ExciteConfig(url="sim://?speed=20&seed=4&preset=hardware&disconnect_every=40", depths_m=(0.3, 0.6),
                          hold_s=60.0,
                          recorder=RecorderConfig(directory=tmp_path))
    with pytest.raises(GroundStationError, match="link lost") as raised:
        excite(config)
    assert "told to surface" in str(raised.value)
    recorded = sorted(tmp_path.glob("*.mcap"))
    assert len(recorded) == 1 and len(open_recording(recorded[0]).samples()) > 0
