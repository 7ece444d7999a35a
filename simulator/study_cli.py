"""The `study` command: parse, run the study with a progress bar, write the results, map errors."""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from learning import LearningError, learner_preset
from simulator.errors import SimulatorError
from simulator.parameters import load_params, preset
from simulator.study import run_study
from simulator.study_output import build_summary, prepare_out_dir, write_results


def study(
    preset_name: Annotated[str, typer.Option("--preset", help="paper or hardware")] = "paper",
    learner: Annotated[str, typer.Option(help="paper, actuator3, rmax or literal")] = "paper",
    trials: Annotated[int, typer.Option(help="independent learning trials")] = 100,
    episodes: Annotated[int, typer.Option(help="episodes per trial")] = 400,
    out: Annotated[Path, typer.Option(help="output folder")] = Path("study-out"),
    seed: Annotated[int, typer.Option(help="seed of every trial's random streams")] = 0,
    params_file: Annotated[Path | None, typer.Option("--params", help="TOML/JSON overrides")] = None,
    as_json: Annotated[bool, typer.Option("--json", help="print summary.json to stdout")] = False,
) -> None:
    """Run N trials x E episodes of a learner on the simulated plant; CSV, npz, summary.json, figures."""
    err = Console(stderr=True)
    try:
        params = preset(preset_name)
        if params_file is not None:
            params = load_params(params_file, params)
        config = learner_preset(learner)
        if trials <= 0 or episodes <= 0:
            raise SimulatorError(f"--trials and --episodes must be positive (got {trials} and {episodes})")
        out_dir = prepare_out_dir(out)
        with Progress(
            TextColumn("[bold]study[/] {task.description}"), BarColumn(), MofNCompleteColumn(),
            TimeElapsedColumn(), console=err, transient=as_json,
        ) as bar:
            task = bar.add_task(f"{preset_name}/{learner}", total=trials * episodes)
            result = run_study(params, config, trials, episodes, seed,
                               on_progress=lambda done: bar.update(task, completed=done))
            bar.update(task, completed=trials * episodes)
        summary = build_summary(result, params, config, preset_name, learner)
        write_results(result, summary, config, params.episode_limit_s, out_dir)
    except (SimulatorError, LearningError) as e:
        print(f"error: {e}", file=sys.stderr)
        raise typer.Exit(2) from None
    if as_json:
        print(json.dumps(summary, indent=2))
    else:
        curves = summary["alc_curves"]
        median = curves["median"]["stable_from"]
        best = curves["best_quarter_q75"]["stable_from"]
        err.print(
            f"wall {result.wall_s:.1f} s on {result.threads} threads; median ALC stable from {median}, "
            f"best quarter from {best}; results in {out_dir}"
        )
