"""`dive fit` on the C firmware in QEMU: the manoeuvre flown by the emulated MCU, its C plant's figures recovered.

The C plant (firmware/src/plant.c, sensor.c) has the `hardware` preset's figures built in and takes no plant
file, so its truth is fixed; the fit starts far from it (added mass 0.06 kg, drag 1.7 kg/m) and must find it.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from simulator.parameters import neutral_alpha_deg, preset

pytestmark = pytest.mark.slow

C_SENSOR_NOISE_PA = 6.5  # firmware/src/sensor.c


def test_the_fit_recovers_the_c_plant(tmp_path: Path) -> None:
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not found: the QEMU tests need it")
    start = tmp_path / "start.toml"
    start.write_text("[plant]\nadded_mass_kg = 0.06\ndrag_kgpm = 1.7\n")
    done = subprocess.run([sys.executable, "-m", "groundstation.cli.app", "fit", "--excite",
                           "sim://?firmware=qemu&speed=max&seed=4", "--hold", "20", "--params", str(start), "--json"],
                          capture_output=True, text=True, timeout=280, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    estimates = json.loads(done.stdout)["estimates"]
    truth = preset("hardware")
    expected = {"added_mass_kg": truth.added_mass_kg, "drag_kgpm": truth.drag_kgpm,
                "alpha_rate_dps": truth.alpha_rate_dps, "pressure_noise_pa": C_SENSOR_NOISE_PA,
                "neutral_angle_deg": neutral_alpha_deg(truth)}
    goals = {"added_mass_kg": 0.05 * truth.added_mass_kg, "drag_kgpm": 0.05 * truth.drag_kgpm,
             "alpha_rate_dps": 0.05 * truth.alpha_rate_dps, "pressure_noise_pa": 0.1 * C_SENSOR_NOISE_PA,
             "neutral_angle_deg": 0.3}
    for name, value in expected.items():
        found = estimates[name]
        assert found["identified"], name
        error = abs(found["value"] - value)
        assert error <= 1.5 * found["half_width_95"] and error <= goals[name], f"{name}: {found} vs {value}"
