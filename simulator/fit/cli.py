"""The `fit` command: read recordings, fit the plant with a progress bar, write the plant file, say what it found."""

from __future__ import annotations

import json
import sys
import time
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer
from rich.console import Console
from rich.progress import Progress, SpinnerColumn, TaskID, TextColumn, TimeElapsedColumn

from simulator.errors import ParamsError, SimulatorError, say_error
from simulator.fit.estimate import DEPTH_SCALE_RANGE, FitResult, fit_recordings, predict_recordings
from simulator.fit.output import plant_toml, report_lines, result_json, write_text
from simulator.parameters import PlantParams, load_params, preset, read_param_table, with_overrides

EXIT_FAILED = 1
EXIT_BAD_ARGUMENT = 2
SHOW_PROGRESS_AFTER_S = 1.0
CHECK_WINDOW_S = 30.0  # open-loop prediction from each window's start, as the hidden-truth test judges it


class _LazyProgress:
    """A progress display that appears only once the fit has run for a second (a short fit prints nothing)."""

    def __init__(self, console: Console) -> None:
        self._console = console
        self._started = time.perf_counter()
        self._progress: Progress | None = None
        self._task: TaskID | None = None

    def __call__(self, evaluations: int, rms_m: float) -> None:
        self._show(f"{evaluations} runs of the plant, depth RMS {1000 * rms_m:.3f} mm")

    def reading(self, samples: int) -> None:
        self._show(f"reading: {samples} samples")

    def _show(self, description: str) -> None:
        if self._progress is None:
            if time.perf_counter() - self._started < SHOW_PROGRESS_AFTER_S:
                return
            self._progress = Progress(SpinnerColumn(), TextColumn("[bold]fit[/] {task.description}"),
                                      TimeElapsedColumn(), console=self._console, transient=True)
            self._progress.start()
            self._task = self._progress.add_task("")
        assert self._task is not None
        self._progress.update(self._task, description=description)

    def stop(self) -> None:
        if self._progress is not None:
            self._progress.stop()


def _base(preset_name: str, params_file: Path | None) -> tuple[PlantParams, str, dict[str, Any]]:
    base = preset(preset_name)
    if params_file is None:
        return base, f"preset {preset_name}", {}
    fields = read_param_table(params_file)
    return with_overrides(base, fields), f"preset {preset_name} with {params_file}", fields


def _check(recordings: list[Path], base: PlantParams, plant_file: Path, as_json: bool, err: Console) -> None:
    """`fit --check PLANT`: the plant run open loop under the recorded commands, its residual against the noise."""
    try:
        plant = load_params(plant_file, base)
    except SimulatorError as e:
        say_error(str(e))
        raise typer.Exit(EXIT_BAD_ARGUMENT) from None
    try:
        windows, rms = predict_recordings(recordings, plant, CHECK_WINDOW_S)
    except SimulatorError as e:
        say_error(str(e))
        raise typer.Exit(EXIT_FAILED) from None
    lengths = windows.ends - windows.starts
    overall = float(np.sqrt(np.sum(rms**2 * lengths) / np.sum(lengths)))
    noise_m = plant.pressure_noise_pa / (plant.water_density_kgpm3 * plant.gravity_mps2)
    report = {"plant": str(plant_file), "residual_rms_m": overall, "worst_window_rms_m": float(rms.max()),
              "noise_rms_m": noise_m, "windows": windows.count, "window_s": CHECK_WINDOW_S,
              "seconds": windows.seconds}
    if as_json:
        print(json.dumps(report))
        return
    err.print(f"residual against {plant_file}: {1000 * overall:.3f} mm RMS over {windows.count} windows of up to "
              f"{CHECK_WINDOW_S:g} s (worst {1000 * float(rms.max()):.3f} mm; the plant's noise "
              f"{1000 * noise_m:.3f} mm)", markup=False, highlight=False)


def _plot(result: FitResult, path: Path) -> None:
    from simulator.fit.plot import plot_fit  # matplotlib loads only when a plot is asked for

    plot_fit(result, path)


def fit(
    recordings: Annotated[list[Path], typer.Argument(help="MCAP recordings (or folders of them) of one agent.")],
    out: Annotated[Path | None, typer.Option(help="Write the plant file here (default: print it).")] = None,
    preset_name: Annotated[str, typer.Option("--preset", help="The figures not fitted (mass, stroke, ...).")] = (
        "hardware"),
    params_file: Annotated[Path | None, typer.Option(
        "--params", help="TOML/JSON figures known for this agent (its mass, ...): fixed in the fit.")] = None,
    window: Annotated[float, typer.Option(help="Longest stretch simulated from one start state, s.")] = 10.0,
    depth_scale: Annotated[float, typer.Option(
        "--depth-scale", help="The sensor's depth-scale error is taken to lie within +/- this (not identifiable "
        "from depth): every interval admits it.")] = DEPTH_SCALE_RANGE,
    plot: Annotated[Path | None, typer.Option(help="PNG of measured against predicted depth.")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="Print the estimates as JSON on stdout.")] = False,
    check: Annotated[Path | None, typer.Option(
        help="Fit nothing: how far the recordings are from this plant file (its residual over 30 s windows).")]
    = None,
) -> None:
    """Fit the plant's figures to recorded depth under the recorded commands; writes a file every --params takes.

    `dive fit --excite URL [--depths 0.3,0.6,0.4,0.8,0.3] [--hold 30] [--max-depth 1.0]` first flies a manoeuvre:

    hover at each depth for --hold s of agent time, recorded into recordings/, then fitted (docs/fitting.md).
    """
    # soft_wrap: a line of text (a path, a figure) is never broken by us.
    err = Console(stderr=True, width=None if sys.stderr.isatty() else 200, soft_wrap=True)
    try:
        if not window > 0:
            raise ParamsError(f"--window must be positive (got {window})")
        if not 0.0 <= depth_scale < 0.5:
            raise ParamsError(f"--depth-scale must lie within 0 .. 0.5 (got {depth_scale})")
        base, base_label, base_fields = _base(preset_name, params_file)
    except SimulatorError as e:
        say_error(str(e))
        raise typer.Exit(EXIT_BAD_ARGUMENT) from None
    if check is not None:
        _check(recordings, base, check, as_json, err)
        return
    progress = _LazyProgress(err)
    try:
        result = fit_recordings(recordings, base, window, progress, progress.reading, depth_scale)
    except ParamsError as e:
        say_error(str(e))
        raise typer.Exit(EXIT_BAD_ARGUMENT) from None
    except SimulatorError as e:
        say_error(str(e))
        raise typer.Exit(EXIT_FAILED) from None
    finally:
        progress.stop()
    text = plant_toml(result, base_label, base_fields)
    for target, write in ((out, lambda path: write_text(path, text)), (plot, lambda path: _plot(result, path))):
        if target is None:
            continue
        try:
            target.parent.mkdir(parents=True, exist_ok=True)  # as `dive study --out` and `dive run --out` do
            write(target)
        except (OSError, ValueError) as e:
            say_error(f"cannot write {target}: {getattr(e, 'strerror', None) or e}")
            raise typer.Exit(EXIT_FAILED) from None
    for note in result.notes:
        err.print(f"note: {note}", markup=False, highlight=False)
    for line in report_lines(result):
        err.print(line, markup=False, highlight=False)
    if as_json:
        print(json.dumps(result_json(result), indent=2))
    elif out is None:
        print(text, end="")
    else:
        err.print(f"plant written to {out}", markup=False, highlight=False)
