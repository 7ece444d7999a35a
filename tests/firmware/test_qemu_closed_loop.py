"""The firmware on an emulated Cortex-M4 (QEMU mps2-an386) against the unchanged ground station.

The ELF is the real build (`make -C firmware qemu`): core, learner, C plant and sensor, the board's
UART bridged by QEMU to a loopback TCP port. The tests talk to it over that socket, as `dive` would.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

from protocol import Mode, messages
from simulator.serve.firmware_qemu import ELF_ENV, QemuAgent, QemuConfig, build_elf
from tests.firmware.qemu_link import read_frames
from tests.reliability.recordings import assert_complete, dive, read

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def elf(tmp_path_factory: pytest.TempPathFactory) -> Path:
    for tool, package in (("arm-none-eabi-gcc", "gcc-arm-none-eabi"), ("qemu-system-arm", "qemu-system-arm")):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not found: the QEMU tests need {package}")
    return build_elf(tmp_path_factory.mktemp("qemu-build"))


@pytest.fixture
def agent(elf: Path, tmp_path: Path) -> Iterator[QemuAgent]:
    with QemuAgent(QemuConfig(seed=11, node_id=0x0BADCAFE, diag_path=tmp_path / "uart1.txt"), elf) as running:
        yield running


def test_emulated_agent_says_hello(agent: QemuAgent) -> None:
    """Boot: HELLO (repeated until the ground answers) with the node id QEMU's loader wrote, then IDLE."""
    frames = read_frames(agent.address, 10.0, until=messages.Hello)
    hellos = [m for m in frames if isinstance(m, messages.Hello)]
    assert hellos, f"no HELLO in {len(frames)} frames"
    assert hellos[0].node_id == 0x0BADCAFE
    frames = read_frames(agent.address, 5.0, until=messages.Sample)
    samples = [m for m in frames if isinstance(m, messages.Sample)]
    assert samples and samples[-1].mode == Mode.IDLE
    assert abs(samples[-1].depth_m) < 0.05  # afloat at the surface, read through the C sensor (noise +-)


def test_dive_run_records_learning_on_the_emulated_mcu(agent: QemuAgent, tmp_path: Path) -> None:
    """dive run records a complete session with its learning curve: every sample once, three episodes."""
    out = tmp_path / "qemu.mcap"
    done = dive("run", agent.address, "--episodes", "3", "--viewer", "none", "--out", str(out), timeout_s=120)
    assert done.returncode == 0, done.stderr[-2000:]
    rec = read(out)
    assert_complete(rec, 3)
    assert len(rec.samples) > 100
    assert agent.running  # the firmware did not fault
    assert "FAULT" not in (agent.config.diag_path.read_text() if agent.config.diag_path else "")


def test_sim_url_serves_the_qemu_firmware(elf: Path, tmp_path: Path) -> None:
    """sim://?firmware=qemu: `python -m simulator serve --firmware qemu` starts QEMU and prints its address."""
    out = tmp_path / "sim.mcap"
    env = {**os.environ, ELF_ENV: str(elf)}
    done = dive("run", "sim://?firmware=qemu&speed=max&seed=4", "--episodes", "1", "--viewer", "none",
                "--out", str(out), env=env, timeout_s=120)
    assert done.returncode == 0, done.stderr[-2000:]
    assert_complete(read(out), 1)


def test_qemu_refuses_options_it_cannot_honour() -> None:
    done = subprocess.run([sys.executable, "-m", "simulator", "serve", "--firmware", "qemu", "--drop", "0.1"],
                          capture_output=True, text=True, timeout=60, check=False)
    assert done.returncode == 2
    assert done.stderr.strip() == ("python -m simulator: --firmware qemu runs its own C plant: fault options do not "
                                   "apply")


# The dive check groups that need no long stay in one mode: at --speed max an episode of the hardware
# preset lasts a few ms of wall time, too short for the mode-matrix checks to meet LEARNING reliably.
CHECK_GROUPS = ("handshake", "junk", "timesync", "ack", "signing", "dump", "log")


def test_dive_check_passes_against_the_emulated_agent_with_a_key(elf: Path, tmp_path: Path) -> None:
    """The signing key reaches the firmware through QEMU's loader; dive check signs and the agent conforms."""
    key = bytes(range(32))
    key_file = tmp_path / "agent.key"
    key_file.write_text(key.hex())
    key_file.chmod(0o600)  # dive refuses a key file others can read
    with QemuAgent(QemuConfig(seed=12, key=key), elf) as running:
        only = [arg for group in CHECK_GROUPS for arg in ("--only", group)]
        done = dive("check", running.address, "--allow-motion", "--json", "--key-file", str(key_file), *only,
                    timeout_s=120)
    assert done.stdout.startswith("{"), done.stderr[-2000:]
    report = json.loads(done.stdout)
    failed = [(c["id"], c["detail"]) for c in report["checks"] if c["result"] == "FAIL"]
    assert not failed, failed
    signed = [c for c in report["checks"] if c["id"].startswith("signing.") and c["result"] == "PASS"]
    assert len(signed) >= 8, "the signing checks did not run: was the key not taken?"
    assert done.returncode == 0
