"""`dive fit` on bad input (one line, non-zero exit) and on data that cannot identify every figure."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
from mcap.writer import Writer
from typer.testing import CliRunner

from protocol import Mode
from simulator.cli import app
from simulator.fit.estimate import fit_recordings, fit_samples
from simulator.fit.model import simulate
from simulator.fit.output import plant_toml, report_lines, result_json
from simulator.fit.reader import Samples
from simulator.fit.windows import Windows
from simulator.parameters import neutral_alpha_deg, preset


def _fit_cli(*args: str) -> subprocess.CompletedProcess[str]:
    """`python -m simulator fit ARGS` in a process of its own, as `dive fit` runs it."""
    return subprocess.run([sys.executable, "-m", "simulator", "fit", *args], capture_output=True, text=True,
                          timeout=120)


def _fit_here(*args: str) -> subprocess.CompletedProcess[str]:
    """The same command in this process (its exit code and stderr alike): an interpreter start cheaper."""
    done = CliRunner().invoke(app, ["fit", *args])
    assert done.exception is None or isinstance(done.exception, SystemExit), done.exception  # no traceback
    return subprocess.CompletedProcess(["fit", *args], done.exit_code, done.stdout, done.stderr)


def _one_line_failure(done: subprocess.CompletedProcess[str], words: str) -> None:
    assert done.returncode != 0
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and words in lines[0] and "Traceback" not in done.stderr, done.stderr


def test_a_missing_recording_is_one_line(tmp_path: Path) -> None:
    _one_line_failure(_fit_cli(str(tmp_path / "absent.mcap")), "no such recording")  # a real process, once


def test_a_file_that_is_not_mcap_is_one_line(tmp_path: Path) -> None:
    bad = tmp_path / "noise.mcap"
    bad.write_bytes(np.random.default_rng(1).bytes(5000))
    _one_line_failure(_fit_here(str(bad)), "not an MCAP recording")


def test_a_recording_without_diving_says_there_is_nothing_to_fit(tmp_path: Path) -> None:
    path = tmp_path / "idle.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        channel = writer.register_channel("/agent/SAMPLE", "json", 0)
        for i in range(100):  # an agent idling at the surface: once a second, depth 0
            body = (f'{{"t_us":{i * 1_000_000},"sample":{i},"depth_m":0.0,"actuator_deg":65.0,'
                    f'"actuator_cmd_deg":65.0,"mode":0}}')
            writer.add_message(channel, i * 1_000_000_000, body.encode(), i * 1_000_000_000)
        writer.finish()
    _one_line_failure(_fit_here(str(path)), "nothing to fit")


def test_a_bad_window_is_refused_before_reading(tmp_path: Path) -> None:
    _one_line_failure(_fit_here(str(tmp_path), "--window", "0"), "--window must be positive")


def _hover_samples(step_deg: float) -> Samples:
    """A minute of hovering near neutral under small command steps: slow, so drag shows no effect."""
    params = preset("hardware")
    t = np.arange(0.0, 60.0, 0.025)
    neutral = neutral_alpha_deg(params)
    cmd = neutral + step_deg * np.where((t // 10.0) % 2 == 0, 1.0, -1.0)
    windows = Windows(t_s=t, depth_m=np.zeros_like(t), alpha_deg=np.full_like(t, neutral), cmd_deg=cmd,
                      starts=np.array([0]), ends=np.array([len(t)]))
    depth, alpha = simulate(params, windows, np.array([0.4]), np.array([0.0]))
    noise_m = params.pressure_noise_pa / (params.water_density_kgpm3 * params.gravity_mps2)
    measured = depth + np.random.default_rng(2).normal(0.0, noise_m, len(t))
    return Samples(t_s=t, depth_m=measured, alpha_deg=alpha, cmd_deg=cmd,
                   mode=np.full(len(t), int(Mode.HOVER)), index=np.arange(len(t)), run=np.zeros(len(t), dtype=int),
                   episode_start=np.zeros(len(t), dtype=bool), files=[Path("synthetic")], notes=[])


def test_slow_hovering_cannot_identify_drag_and_says_what_would() -> None:
    result = fit_samples(_hover_samples(0.3), preset("hardware"))
    drag = result.estimate("drag_kgpm")
    assert not drag.identified and "needs speeds above 5 cm/s" in drag.needs
    assert drag.value == preset("hardware").drag_kgpm  # kept at the base's value
    # The actuator never falls behind a 0.3 deg step: its rate cannot be measured either.
    assert not result.estimate("alpha_rate_dps").identified
    assert result.estimate("pressure_noise_pa").identified


def _write_samples(path: Path, samples: Samples) -> None:
    """The samples as a recorder writes them: JSON SAMPLE messages on /agent/SAMPLE, in zstd chunks."""
    with open(path, "wb") as stream:
        writer = Writer(stream, chunk_size=16 * 1024)
        writer.start()
        channel = writer.register_channel("/agent/SAMPLE", "json", 0)
        for i in range(len(samples.t_s)):
            body = {"t_us": int(round(samples.t_s[i] * 1e6)), "sample": int(samples.index[i]),
                    "depth_m": float(samples.depth_m[i]), "actuator_deg": float(samples.alpha_deg[i]),
                    "actuator_cmd_deg": float(samples.cmd_deg[i]), "mode": int(samples.mode[i])}
            time_ns = int(round(samples.t_s[i] * 1e9))
            writer.add_message(channel, time_ns, json.dumps(body).encode(), time_ns)
        writer.finish()


def test_a_recording_cut_short_is_fitted_up_to_the_cut(tmp_path: Path) -> None:
    whole, cut = tmp_path / "whole.mcap", tmp_path / "cut.mcap"
    _write_samples(whole, _hover_samples(4.0))
    cut.write_bytes(whole.read_bytes()[: int(whole.stat().st_size * 0.7)])
    result = fit_recordings([cut], preset("hardware"))
    assert any("read up to damage" in note for note in result.notes)
    assert 0.5 * 60.0 < result.windows.seconds < 0.8 * 60.0  # the part before the cut, nothing after
    # 40 s in 4 windows of hovering: the neutral angle is identified (the added mass is not, with the port's lag
    # free beside it and the sandwich's t over 3 windows)
    assert result.estimate("neutral_angle_deg").identified
    done = _fit_here(str(cut))
    assert done.returncode == 0 and "note:" in done.stderr and "Traceback" not in done.stderr


def test_a_disturbance_the_model_lacks_fails_the_diagnostics_and_widens_the_intervals() -> None:
    """Waves the plant has no term for (a 3 mm, 0.2 Hz swell on the depth): the residual is coloured beyond an
    AR(1), the whiteness check fails, one warning line says so, and the intervals are the sandwich's, wider than
    the Jacobian's (which assume the model is the truth)."""
    samples = _hover_samples(4.0)
    samples.depth_m = samples.depth_m + 0.003 * np.sin(2 * np.pi * 0.2 * samples.t_s)
    result = fit_samples(samples, preset("hardware"), depth_scale=0.0)
    assert result.robust and result.warning.startswith("warning: the residuals fail")
    assert [d.name for d in result.diagnostics if not d.passed]
    lines = report_lines(result)
    assert sum(line.startswith("warning:") for line in lines) == 1
    assert result_json(result)["misfit_warning"] == result.warning
    for e in result.estimates:
        if e.identified and e.name in result.hull.free:
            assert e.half_width >= result.hull.half_width(e.name) - 1e-15, e.name


def test_the_residual_diagnostics_pass_on_the_model_itself() -> None:
    result = fit_samples(_hover_samples(4.0), preset("hardware"))
    assert not result.robust and result.warning == ""
    assert [d.name for d in result.diagnostics] == ["magnitude", "whiteness"]
    assert all(d.passed for d in result.diagnostics)
    # The hull is rigid and the gear ideal: what must be >= 0 is, with intervals that reach 0.
    for name in ("compressibility_m3pm", "backlash_deg", "pressure_lag_s", "dead_band_deg"):
        e = result.estimate(name)
        assert e.value >= 0.0
        assert not e.identified or e.value - e.half_width <= 1e-9, f"{name}: {e.value} +/- {e.half_width}"


def test_learning_episodes_give_the_hand_over_offset_as_a_comment_not_a_figure() -> None:
    """Six episodes whose windows were centred 1.5 deg above the neutral angle: the offset is reported, and the
    plant file carries it in a comment only (the recovery controller's own error is in it)."""
    samples = _hover_samples(4.0)
    starts = np.arange(0, len(samples.t_s), len(samples.t_s) // 6)[:6]
    samples.mode = np.full(len(samples.t_s), int(Mode.LEARNING))
    samples.episode_start = np.zeros(len(samples.t_s), dtype=bool)
    samples.episode_start[starts] = True
    neutral = neutral_alpha_deg(preset("hardware"))
    samples.cmd_deg = samples.cmd_deg.copy()
    samples.cmd_deg[starts] = neutral + 1.5
    result = fit_samples(samples, preset("hardware"))
    offset = result.estimate("handover_offset_deg")
    assert offset.identified and abs(offset.value - 1.5) <= offset.half_width
    text = plant_toml(result, "preset hardware", {})
    assert "# handover_offset_deg = 1.5" in text and "\nstart_trim_error_deg" not in text
