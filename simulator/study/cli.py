"""The `study` command: parse, run the studies with a progress bar, write the results, map errors."""

from __future__ import annotations

import json
import sys
from functools import partial
from pathlib import Path
from typing import Annotated, Any

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeElapsedColumn
from rich.table import Table

from learning import LearningError
from simulator.errors import ClusterUnreachableError, SimulatorError, say_error
from simulator.parameters import load_params
from simulator.study.compare import compare_rows, write_compare, write_overlay
from simulator.study.family import family_summary, load_family
from simulator.study.options import Exploration, LearnerOptions, RunSpec, Ties, expand_runs
from simulator.study.output import build_summary, prepare_out_dir, write_results
from simulator.study.runner import StudyResult, run_study


def _seed_list(text: str | None, seed: int) -> list[int]:
    if text is None:
        return [seed]
    try:
        out: list[int] = []
        for part in text.split(","):
            first, _, last = part.partition("-")
            out.extend(range(int(first), int(last or first) + 1))
    except ValueError:
        raise SimulatorError(f"--seeds must be like 0-2 or 0,1,2 (got {text!r})") from None
    if not out:
        raise SimulatorError("--seeds names no seed")
    return out


def study(
    preset_name: Annotated[str, typer.Option("--preset", help="paper or hardware")] = "paper",
    learner: Annotated[str, typer.Option(help="a learner of the list below (hardware: the robot's)")] = "paper",
    compare: Annotated[str | None, typer.Option(
        help="comma-separated learners or preset/learner pairs run on the same seeds; ratios to the first "
             "of each preset")] = None,
    trials: Annotated[int, typer.Option(help="independent learning trials (per seed)")] = 100,
    episodes: Annotated[int, typer.Option(help="episodes per trial")] = 400,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("study-out"),
    seed: Annotated[int, typer.Option(help="seed of every trial's random streams")] = 0,
    seeds: Annotated[str | None, typer.Option(help="pool trials of several seeds, e.g. 0-2")] = None,
    params_file: Annotated[Path | None, typer.Option("--params", help="TOML/JSON overrides")] = None,
    plant_family: Annotated[Path | None, typer.Option(
        help="TOML of per-parameter ranges; each trial draws its plant from its seed (docs/families/tank.toml)"
    )] = None,
    z_tol: Annotated[float | None, typer.Option(
        "--z-tol", help="learning region half-height, m (hardware default: both 0.1 and 0.15)")] = None,
    zdot_tol: Annotated[float | None, typer.Option(
        "--zdot-tol", help="learning region half-width in velocity, m/s")] = None,
    exploration: Annotated[Exploration, typer.Option(help="override the learner's exploration")] = (
        Exploration.PRESET),
    bonus: Annotated[float, typer.Option(help="count bonus beta with --exploration bonus")] = 0.5,
    ties: Annotated[Ties, typer.Option(help="when ties between the two actions are drawn")] = Ties.PRESET,
    actuator_bins: Annotated[int | None, typer.Option(help="actuator bins in the state")] = None,
    velocity_diff: Annotated[int | None, typer.Option(
        help="learner velocity from its own k-step depth difference (0: the preset's velocity)")] = None,
    dirichlet: Annotated[float | None, typer.Option(
        help="shared model: local counts with the shared histogram as a prior of this weight")] = None,
    max_sweeps: Annotated[int | None, typer.Option(help="planning sweeps per call at most")] = None,
    sweep: Annotated[Path | None, typer.Option(help="run the grid of a sweep TOML file instead")] = None,
    cluster: Annotated[str | None, typer.Option(
        help="with --sweep: Dask scheduler address, e.g. tcp://scheduler:8786")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print summary.json (or compare.json) to stdout")] = False,
) -> None:
    """Run N trials x E episodes of learners on the simulated plant; CSV, npz, summary.json, figures."""
    # A log file gets the table at full width (a terminal keeps its own width).
    # soft_wrap: a line of text (a path, a figure) is never broken by us; the table sets its own layout.
    err = Console(stderr=True, width=None if sys.stderr.isatty() else 200, soft_wrap=True)
    try:
        if sweep is not None:
            from simulator.study.sweep import run_sweep_command

            run_sweep_command(sweep, out, cluster, err)
            return
        if cluster is not None:
            raise SimulatorError("--cluster needs --sweep")
        if trials <= 0 or episodes <= 0:
            raise SimulatorError(f"--trials and --episodes must be positive (got {trials} and {episodes})")
        options = LearnerOptions(exploration, bonus, ties, actuator_bins, velocity_diff, dirichlet, max_sweeps,
                                 z_tol, zdot_tol)
        override = None if params_file is None else (lambda p: load_params(params_file, p))
        runs = expand_runs(compare.split(",") if compare else [learner], preset_name, options, override)
        seed_list = _seed_list(seeds, seed)
        # Every trial's plant is drawn (and checked) before any trial runs.
        families = [None if plant_family is None else load_family(plant_family, run.params) for run in runs]
        out_dir = prepare_out_dir(out)
        results: list[StudyResult] = []
        summaries: list[dict[str, Any]] = []
        with Progress(
            TextColumn("[bold]study[/] {task.description}"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), console=err, transient=as_json,
        ) as bar:
            tasks = [bar.add_task(run.label, total=trials * len(seed_list) * episodes) for run in runs]
            for run, task, family in zip(runs, tasks, families, strict=True):
                plants = None if family is None else [
                    family.draw(run.params, k, t) for k in seed_list for t in range(trials)]
                result = run_study(run.params, run.config, trials, episodes, seed_list[0],
                                   on_progress=partial(_advance, bar, task), seeds=seed_list, plants=plants)
                bar.update(task, completed=trials * len(seed_list) * episodes)
                summary = build_summary(result, run.params, run.config, run.preset, run.learner)
                if family is not None and plants is not None:
                    summary.update(family_summary(family, plants))
                run_dir = out_dir if len(runs) == 1 else prepare_out_dir(out_dir / run.slug)
                write_results(result, summary, run.config, run.params.episode_limit_s, run_dir)
                results.append(result)
                summaries.append(summary)
        if len(runs) > 1:
            rows = _write_comparison(runs, results, summaries, out_dir)
    except ClusterUnreachableError as e:  # the input was right; the cluster is down
        say_error(str(e))
        raise typer.Exit(1) from None
    except (SimulatorError, LearningError) as e:
        say_error(str(e))
        raise typer.Exit(2) from None
    if len(runs) > 1:
        if as_json:
            print(json.dumps(rows, indent=2))
        else:
            _print_table(rows, err)
            for run, summary in zip(runs, summaries, strict=True):
                _print_quality(run.label, summary, err)
            err.print(f"results in {out_dir}")
        return
    summary, result = summaries[0], results[0]
    if as_json:
        print(json.dumps(summary, indent=2))
    else:
        curves = summary["alc_curves"]
        median = curves["median"]["stable_from"]
        best = curves["best_quarter_q75"]["stable_from"]
        own = summary["across_trials"]["alc_stable_from"]
        err.print(
            f"wall {result.wall_s:.1f} s on {result.threads} threads; median ALC stable from {median}, "
            f"best quarter from {best}; never stable {_percent(own['fraction_never'], own['fraction_never_ci95'])}"
            f"; results in {out_dir}"
        )
        _print_quality(runs[0].label, summary, err)


def _print_quality(label: str, summary: dict[str, Any], console: Console) -> None:
    """Hold quality beside the recovery controller's, and the hardware goals judged on their intervals."""
    hold = summary.get("hold_quality")
    if hold is not None and hold["learner"]["episodes"]:
        mine, rec = hold["learner"], hold.get("recovery", {})

        def med(block: dict[str, Any], key: str) -> str:
            return _fmt(block.get(key, {}).get("median"))

        # Issue 43: the oscillation (RMS about the mean) is what a policy adds; the offset is what the sensor sets.
        console.print(
            f"{label} hold (median over {mine['episodes']} late successful episodes; recovery controller on the "
            f"same plant and plant time in brackets): oscillation RMS {med(mine, 'oscillation_rms_mm')} mm "
            f"({med(rec, 'oscillation_rms_mm')}), offset {med(mine, 'offset_mm')} mm ({med(rec, 'offset_mm')}), "
            f"RMS {med(mine, 'rms_depth_error_mm')} mm ({med(rec, 'rms_depth_error_mm')}), "
            f"peak-to-peak {med(mine, 'peak_to_peak_mm')} mm ({med(rec, 'peak_to_peak_mm')}), "
            f"travel {med(mine, 'actuator_travel_deg_per_min')} deg/min "
            f"({med(rec, 'actuator_travel_deg_per_min')})")
    for line in summary.get("hardware_goals", []):
        console.print(f"{label} goal {line}")


def _advance(bar: Progress, task: TaskID, done: int) -> None:
    bar.update(task, completed=done)


def _write_comparison(
    runs: list[RunSpec], results: list[StudyResult], summaries: list[dict[str, Any]], out_dir: Path
) -> list[dict[str, Any]]:
    limits = [run.params.episode_limit_s for run in runs]
    rows = compare_rows([r.label for r in runs], [r.preset for r in runs], results, summaries, limits)
    write_compare(rows, out_dir)
    write_overlay([r.label for r in runs], results, max(limits), out_dir / "compare_fig5_alc.png")
    return rows


def _fmt(value: Any) -> str:
    if value is None:
        return "never"
    if isinstance(value, list):
        return "-".join(_fmt(v) for v in value)
    return f"{value:g}" if isinstance(value, float) else str(value)


def _percent(fraction: float, ci: list[float]) -> str:
    return f"{100 * fraction:.1f} % ({100 * ci[0]:.1f} - {100 * ci[1]:.1f})"


def _print_table(rows: list[dict[str, Any]], console: Console) -> None:
    table = Table(title="study comparison (95 % intervals: bootstrap over trials; Wilson for proportions)")
    for column in ("learner", "trials", "first success", "median ALC stable from", "own stable from (median)",
                   "never stable (Wilson)", "ratio", "ratio to paper's 230", "RAM B", "sweeps/plan (max)"):
        table.add_column(column)
    for r in rows:
        table.add_row(
            r["label"], str(r["trials"]),
            f"{_fmt(r['first_success_median'])} ({_fmt(r['first_success_ci95'])})",
            f"{_fmt(r['median_alc_stable_from'])} ({_fmt(r['median_alc_ci95'])})",
            f"{_fmt(r['own_stable_from_median'])} ({_fmt(r['own_stable_from_ci95'])})",
            _percent(r["never_stable_fraction"], r["never_stable_ci95"]),
            f"{_fmt(r['ratio_to_reference'])} ({_fmt(r['ratio_ci95'])})",
            "-" if r["ratio_to_published"] is None else
            f"{_fmt(r['ratio_to_published'])} ({_fmt(r['ratio_to_published_ci95'])})",
            str(r["memory_bytes"]),
            f"{r['sweeps_per_plan_mean']:g} ({r['sweeps_per_plan_max']})",
        )
    console.print(table, soft_wrap=False)
