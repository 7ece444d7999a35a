"""Sweeps: a grid of studies (plant presets x learners x learner parameters x seeds) from a TOML file, run
here one study after another or on a Dask distributed cluster; one results table and a summary plot.

File format (every key optional except learners):

    trials = 100            # per seed
    episodes = 400
    seeds = [0, 1, 2]
    presets = ["paper"]
    learners = ["paper", "shared"]
    plants = ["", "noise2.toml"]  # --params files (relative to this file; "" = the preset as it is)
    plant_family = "tank.toml"    # optional: every trial draws its plant from this family
    [grid]                  # LearnerConfig fields, each a list of values; the grid is their product
    actuator_bins = [1, 3]

Each grid point and seed is one task; a task's trials draw their random streams (and, with a family, their
plants) from (seed, trial) only, so the same file gives the same table here and on any cluster (whose workers
must see the plant files at the same absolute paths).
"""

from __future__ import annotations

import csv
import itertools
import socket
import time
import tomllib
from dataclasses import fields
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import numpy as np
from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from learning import LearnerConfig, LearningError, learner_preset
from simulator.errors import ClusterUnreachableError, SimulatorError, StudyError
from simulator.parameters import PlantParams, load_params, preset, preset_names
from simulator.study.family import PlantFamily, load_family
from simulator.study.output import prepare_out_dir
from simulator.study.runner import run_study
from simulator.study.stats import summarise

_CONFIG_FIELDS = {f.name: f.type for f in fields(LearnerConfig)}
_TIMING_COLUMNS = ("wall_s",)  # the only columns that differ between two runs of one file


def load_sweep(path: Path) -> list[dict[str, Any]]:
    """The tasks of a sweep file, in a fixed order (presets, learners, grid, seeds)."""
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise SimulatorError(f"cannot read sweep file {path}: {e}") from None
    unknown = set(data) - {"trials", "episodes", "seeds", "presets", "learners", "grid", "plants", "plant_family"}
    if unknown:
        raise SimulatorError(f"sweep file {path}: unknown keys {sorted(unknown)}")
    grid = data.get("grid", {})
    if not isinstance(grid, dict) or any(not isinstance(v, list) or not v for v in grid.values()):
        raise SimulatorError(f"sweep file {path}: [grid] must map learner fields to non-empty lists")
    bad = sorted(set(grid) - set(_CONFIG_FIELDS))
    if bad:
        raise SimulatorError(f"sweep file {path}: {bad} are not learner parameters")
    learners = data.get("learners")
    if not isinstance(learners, list) or not learners:
        raise SimulatorError(f"sweep file {path}: learners must be a non-empty list")
    presets = data.get("presets", ["paper"])
    for name in presets:
        if name not in preset_names():
            raise SimulatorError(f"sweep file {path}: unknown preset {name!r}")
    trials, episodes = int(data.get("trials", 100)), int(data.get("episodes", 400))
    if trials <= 0 or episodes <= 0:
        raise SimulatorError(f"sweep file {path}: trials and episodes must be positive")
    plants = [_sweep_path(path, p) for p in _strings(path, data, "plants", [""])]
    family = _sweep_path(path, data.get("plant_family", ""))
    for preset_name, plant in itertools.product(presets, plants):
        _task_params(preset_name, plant, family)  # refuse a bad plant file before hours of computing
    names = sorted(grid)
    tasks = []
    for preset_name, plant, learner in itertools.product(presets, plants, learners):
        for values in itertools.product(*(grid[n] for n in names)):
            overrides = dict(zip(names, values, strict=True))
            try:
                learner_preset(learner, **overrides)  # refuse a bad point before hours of computing
            except (LearningError, TypeError) as e:
                raise SimulatorError(f"sweep file {path}: {learner} with {overrides}: {e}") from None
            for seed in data.get("seeds", [0]):
                tasks.append({"preset": preset_name, "learner": learner, "overrides": overrides,
                              "seed": int(seed), "trials": trials, "episodes": episodes, "plant": plant,
                              "plant_family": family})
    return tasks


def _strings(path: Path, data: dict[str, Any], key: str, default: list[str]) -> list[str]:
    value = data.get(key, default)
    if not isinstance(value, list) or not value or not all(isinstance(v, str) for v in value):
        raise SimulatorError(f"sweep file {path}: {key} must be a non-empty list of file names")
    return value


def _sweep_path(sweep_file: Path, name: Any) -> str:
    """A plant file named in a sweep file, relative to it; "" stays "" (no file)."""
    if not isinstance(name, str):
        raise SimulatorError(f"sweep file {sweep_file}: plant files must be strings")
    return "" if not name else str((sweep_file.parent / name).resolve())


def _task_params(preset_name: str, plant: str, family: str) -> tuple[PlantParams, PlantFamily | None]:
    """The base plant of a task (preset and --params file) and its family, if any."""
    params = preset(preset_name)
    if plant:
        params = load_params(Path(plant), params)
    return params, (load_family(Path(family), params) if family else None)


def sweep_task(task: dict[str, Any]) -> dict[str, Any]:
    """One study of the grid and its statistics as a flat row (runs on a Dask worker as well as here)."""
    params, family = _task_params(task["preset"], task.get("plant", ""), task.get("plant_family", ""))
    config = learner_preset(task["learner"], **task["overrides"])
    plants = None if family is None else [family.draw(params, task["seed"], t) for t in range(task["trials"])]
    result = run_study(params, config, task["trials"], task["episodes"], task["seed"], plants=plants)
    stats = summarise(result.durations_s, params.episode_limit_s, result.seed)
    across, curves = stats["across_trials"], stats["alc_curves"]
    counters = result.counters if result.counters is not None else np.zeros((1, 4), dtype=np.int64)
    return {
        "preset": task["preset"], "learner": task["learner"],
        "plant": Path(task["plant"]).stem if task.get("plant") else "",
        "plant_family": Path(task["plant_family"]).stem if task.get("plant_family") else "",
        **{f"param_{k}": v for k, v in task["overrides"].items()},
        "seed": task["seed"], "trials": task["trials"], "episodes": task["episodes"],
        "first_success_median": across["first_success"]["median"],
        "median_alc_stable_from": curves["median"]["stable_from"],
        "median_alc_ci95_low": curves["median"]["bootstrap"]["ci95"][0],
        "median_alc_ci95_high": curves["median"]["bootstrap"]["ci95"][1],
        "best_quarter_stable_from": curves["best_quarter_q75"]["stable_from"],
        "own_stable_from_median": across["alc_stable_from"]["median"],
        "never_stable_fraction": across["alc_stable_from"]["fraction_never"],
        "never_stable_ci95_low": across["alc_stable_from"]["fraction_never_ci95"][0],
        "never_stable_ci95_high": across["alc_stable_from"]["fraction_never_ci95"][1],
        "success_rate_last_50": stats["success_rate_last_50"],
        "success_rate_last_50_ci95_low": stats["success_rate_last_50_ci95"][0],
        "success_rate_last_50_ci95_high": stats["success_rate_last_50_ci95"][1],
        "memory_bytes": result.memory_bytes,
        "evictions": int(counters[:, 0].sum()),
        "sweeps_per_plan_max": int(counters[:, 2].max()),
        "wall_s": round(result.wall_s, 3),
    }


PROBE_TIMEOUT_S = 3.0


def check_reachable(cluster: str) -> None:
    """A TCP scheduler address that nobody answers fails in seconds (Dask's Client waits its whole timeout first).
    Other schemes (inproc://, tls://...) are left to Dask."""
    parts = urlsplit(cluster if "://" in cluster else f"tcp://{cluster}")
    if parts.scheme != "tcp" or parts.hostname is None:
        return
    try:
        port = parts.port or 8786
        with socket.create_connection((parts.hostname, port), timeout=PROBE_TIMEOUT_S):
            pass
    except (OSError, ValueError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else str(e) or type(e).__name__
        raise ClusterUnreachableError(f"cannot reach the Dask scheduler at {cluster}: {why}") from None


def run_sweep(
    tasks: list[dict[str, Any]], cluster: str | None = None, console: Console | None = None
) -> list[dict[str, Any]]:
    """Every task's row, in task order: here one after another, or on the Dask scheduler at `cluster`."""
    rows: list[dict[str, Any] | None] = [None] * len(tasks)
    if cluster is not None:
        check_reachable(cluster)  # before a bar: a scheduler that is down is one line at once
    with Progress(
        TextColumn("[bold]sweep[/] {task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
        console=console or Console(stderr=True), transient=console is None,
    ) as bar:
        job = bar.add_task(cluster or "local", total=len(tasks))
        if cluster is None:
            for i, task in enumerate(tasks):
                rows[i] = sweep_task(task)
                bar.advance(job)
        else:
            try:
                from distributed import Client, as_completed
            except ImportError:
                raise SimulatorError("--cluster needs Dask's distributed: pip install -e '.[cluster]' in the checkout "
                                     "(or pip install distributed)") from None
            try:
                client = Client(cluster, timeout=10)
            except (OSError, TimeoutError) as e:
                raise ClusterUnreachableError(f"cannot reach the Dask scheduler at {cluster}: {e}") from None
            with client:
                futures = client.map(sweep_task, tasks, pure=False)
                index = {f.key: i for i, f in enumerate(futures)}
                for future in as_completed(futures):
                    rows[index[future.key]] = future.result()
                    bar.advance(job)
    return [r for r in rows if r is not None]


def write_sweep(rows: list[dict[str, Any]], out_dir: Path) -> list[Path]:
    """sweep.csv (one row per grid point and seed) and sweep.png (median ALC stable-from per point)."""
    columns = list(dict.fromkeys(k for r in rows for k in r))
    try:
        table = out_dir / "sweep.csv"
        with table.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=columns)
            writer.writeheader()
            writer.writerows(rows)
        plot = out_dir / "sweep.png"
        _plot(rows, plot)
    except OSError as e:
        raise StudyError(f"cannot write results to {out_dir}: {e.strerror or e}") from e
    return [table, plot]


def _point_label(row: dict[str, Any]) -> str:
    params = ", ".join(f"{k[6:]}={v}" for k, v in row.items() if k.startswith("param_"))
    plant = "+".join(p for p in (row.get("plant"), row.get("plant_family")) if p)
    return f"{row['preset']}{'+' + plant if plant else ''}/{row['learner']}" + (f" ({params})" if params else "")


def _plot(rows: list[dict[str, Any]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    labels = list(dict.fromkeys(_point_label(r) for r in rows))
    fig, ax = plt.subplots(figsize=(7.2, 0.45 * len(labels) + 1.4))
    for r in rows:
        y = labels.index(_point_label(r))
        never = r["median_alc_stable_from"] is None
        x = r["episodes"] if never else r["median_alc_stable_from"]
        ax.errorbar(x, y, xerr=[[x - r["median_alc_ci95_low"]], [r["median_alc_ci95_high"] - x]],
                    fmt="x" if never else "o", color=f"C{r['seed'] % 10}", capsize=3, alpha=0.8)
    ax.set_yticks(range(len(labels)), labels, fontsize=7)
    ax.set_xlabel("median ALC stable from episode (95 % bootstrap; x = never); colour = seed")
    ax.set_title("sweep")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def run_sweep_command(path: Path, out: Path, cluster: str | None, console: Console) -> None:
    """`dive study --sweep FILE [--cluster URL]`."""
    tasks = load_sweep(path)
    out_dir = prepare_out_dir(out)
    start = time.perf_counter()
    rows = run_sweep(tasks, cluster, console)
    write_sweep(rows, out_dir)
    console.print(f"{len(rows)} studies in {time.perf_counter() - start:.1f} s; results in {out_dir}/sweep.csv")
