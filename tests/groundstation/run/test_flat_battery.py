"""A run whose agent's battery runs flat stops in one line instead of restarting an agent that surfaces at once.

The virtual agent surfaces below low_batt_v (SPEC s. 6); set just under a full battery's voltage, it runs flat
within minutes of agent time. Before, the run counted only finished episodes against its budget and restarted
the agent up to ten times, each start aborted at once: minutes of a run that could not go on.
"""

from __future__ import annotations

import time
from pathlib import Path

import pytest

from groundstation.recording.info import summarize
from tests.groundstation.hub_helpers import dive

pytestmark = pytest.mark.slow


def test_a_flat_battery_ends_the_run_with_one_line_and_a_complete_recording(tmp_path: Path) -> None:
    params = tmp_path / "tank.toml"
    params.write_text("low_batt_v = 4.15\n")  # a full battery reads 4.17-4.20 V
    out = tmp_path / "run.mcap"
    started = time.monotonic()
    done = dive(tmp_path / "runtime", "run", "sim://?speed=max&seed=3", "--episodes", "40", "--params", str(params),
                "--out", str(out), "--viewer", "none", timeout=240)
    took_s = time.monotonic() - started
    assert "battery is flat" in done.stdout + done.stderr, (done.stdout, done.stderr)
    assert "starting it again" not in done.stdout, done.stdout
    assert "Traceback" not in done.stderr
    summary = summarize(out)
    assert summary.complete and summary.samples_missing == 0
    assert took_s < 120, f"the run took {took_s:.0f} s to give up"
