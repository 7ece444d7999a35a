"""`make -C firmware teensy` compiles the core and the sketch's glue for the MK20DX256 (soft float) and links both
variants (paper learner, actuator-state learner) inside the chip's 256 KB flash and 64 KB RAM."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import pytest

from tests.firmware.core_build import FIRMWARE

pytestmark = pytest.mark.slow
FLASH_BYTES = 256 * 1024
RAM_BYTES = 64 * 1024


def test_teensy_build_fits_the_mk20dx256(tmp_path: Path) -> None:
    for tool in ("arm-none-eabi-gcc", "arm-none-eabi-g++", "arm-none-eabi-size", "make", "cc"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not on PATH: the Teensy build test is skipped")
    result = subprocess.run(["make", "-s", "-C", str(FIRMWARE), "teensy", f"BUILD={tmp_path}"],
                            capture_output=True, text=True, timeout=300, check=False)
    assert result.returncode == 0, result.stderr + result.stdout
    rows = re.findall(r"^\s*(\d+)\s+(\d+)\s+(\d+)\s+\d+\s+[0-9a-f]+\s+(\S+)$", result.stdout, re.MULTILINE)
    sizes = {Path(path).parent.name: (int(text), int(data), int(bss)) for text, data, bss, path in rows}
    assert set(sizes) == {"paper", "actuator3", "shared-bins13", "shared-z20"}, result.stdout
    for text, data, bss in sizes.values():
        assert text + data <= FLASH_BYTES and data + bss <= RAM_BYTES
    # The actuator-state learner (S = 301) needs more RAM than the paper's (S = 101), the code is the same.
    assert sizes["actuator3"][2] > sizes["paper"][2] and sizes["actuator3"][0] == sizes["paper"][0]
    # The shared model with 13 bins (S = 1301): its learner (16 096 B, room for planning's early stop included) and
    # 4 x 4S snapshot copies (20 816 B) in less bss than actuator3's, the same code.
    assert sizes["paper"][2] < sizes["shared-bins13"][2] < sizes["actuator3"][2]
    assert sizes["shared-bins13"][0] == sizes["shared-z20"][0] == sizes["paper"][0]
    # The hardware preset's best (S = 1401): learner 11 732 B and snapshots 22 416 B, less than shared-bins13's
    # 16 096 + 20 816 B.
    assert sizes["paper"][2] < sizes["shared-z20"][2] < sizes["shared-bins13"][2]
    for variant in sizes:  # built with the Cortex-M4 soft-float ABI: no FPU instructions
        attributes = subprocess.run(["arm-none-eabi-readelf", "-A", str(tmp_path / "teensy" / variant / "agent.elf")],
                                    capture_output=True, text=True, check=False).stdout
        assert "Tag_FP_arch" not in attributes and "Tag_ABI_VFP_args" not in attributes
