"""A plant file on the QEMU board: every figure of the C plant and sensor reaches it at boot, imperfections included."""

from __future__ import annotations

import dataclasses
import re
import shutil
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from protocol import Mode, messages
from simulator.cli import app
from simulator.parameters import PlantParams, preset
from simulator.serve.firmware_qemu import FIRMWARE_DIR, PLANT_FIELDS, QemuAgent, QemuConfig, build_elf
from tests.firmware.qemu_link import read_frames

RHO_G = 1000.0 * 9.81  # the firmware's depth from pressure (config.h)


def test_the_boot_block_carries_the_figures_bootargs_h_reads_in_its_order() -> None:
    header = (FIRMWARE_DIR / "boards" / "qemu" / "bootargs.h").read_text()
    block = header.split("#define BOOTARGS_PLANT(X)", 1)[1].split("\n\n", 1)[0]
    assert tuple(re.findall(r"X\((\w+)\)", block)) == PLANT_FIELDS
    fields = {f.name for f in dataclasses.fields(PlantParams)}
    assert set(PLANT_FIELDS) <= fields


@pytest.mark.slow
def test_a_qemu_agent_given_a_sensor_bias_and_drift_reads_them(tmp_path: Path) -> None:
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not found: the QEMU tests need it")
    bias_pa, drift_pa_per_s = 500.0, 2.0
    plant = dataclasses.replace(preset("hardware"), pressure_bias_pa=bias_pa, pressure_drift_pa_per_s=drift_pa_per_s,
                                pressure_noise_pa=1.0)
    with QemuAgent(QemuConfig(seed=3, plant=plant), build_elf()) as agent:
        frames = read_frames(agent.address, 1.5)
    samples = [f for f in frames if isinstance(f, messages.Sample) and f.mode == Mode.IDLE]
    assert len(samples) > 100
    t_s = np.array([s.t_us for s in samples]) * 1e-6
    pressure_pa = np.array([s.pressure_pa for s in samples])
    depth_m = np.array([s.depth_m for s in samples])
    # Afloat at the surface: every reading is the surface's pressure, the bias and the drift so far.
    slope, intercept = np.polyfit(t_s, pressure_pa, 1)
    assert slope == pytest.approx(drift_pa_per_s, rel=0.01)
    assert intercept == pytest.approx(plant.surface_pressure_pa + bias_pa, abs=3.0)
    # The agent zeroes its depth at boot (P0 holds the bias), so the depth it reports grows with the drift alone
    # (within the reading's noise and 1 Pa steps, and P0's own noise: 1 mm is 10 Pa).
    assert np.polyfit(t_s, depth_m, 1)[0] == pytest.approx(drift_pa_per_s / RHO_G, rel=0.01)
    assert np.abs(depth_m - drift_pa_per_s * t_s / RHO_G).max() < 0.001


@pytest.mark.parametrize(("option", "text", "says"), [
    ("--plant", "[plant]\nobserver_tau_s = 0.3\n", "observer_tau_s do not apply to --firmware qemu"),
    ("--plant", "[plant]\ndrag_kgpm = -1.0\n", "must not be negative"),
    ("--plant", "[plant]\ndrgg_kgpm = 1.0\n", "unknown parameter 'drgg_kgpm'"),
    ("--params", "z_tol_m = 0.2\n", "agent parameters (z_tol_m) do not apply to --firmware qemu"),
])
def test_a_figure_the_c_plant_cannot_take_is_refused_in_one_line(tmp_path: Path, option: str, text: str,
                                                                 says: str) -> None:
    path = tmp_path / "plant.toml"
    path.write_text(text)
    done = CliRunner().invoke(app, ["serve", "--firmware", "qemu", "--tcp", "127.0.0.1:0", option, str(path)])
    assert done.exit_code == 2 and says in done.stderr, done.stderr  # before QEMU starts
    assert done.exception is None or isinstance(done.exception, SystemExit)
    assert len(done.stderr.strip().splitlines()) == 1
