"""Writes a study's results: curves as CSV and npz, summary.json, figures; checks the folder first."""

from __future__ import annotations

import csv
import json
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from learning import LearnerConfig, resolve_learner
from simulator.errors import StudyError
from simulator.parameters import PlantParams, is_hardware
from simulator.study.figures import write_figures
from simulator.study.goals import goal_lines
from simulator.study.hold import hold_summary
from simulator.study.runner import StudyResult
from simulator.study.stats import moving_average, summarise


def prepare_out_dir(out_dir: Path) -> Path:
    """Create the folder and prove it is writable before hours of computing, not after."""
    try:
        out_dir.mkdir(parents=True, exist_ok=True)
        probe = out_dir / ".write-test"
        probe.write_text("ok")
        probe.unlink()
    except OSError as e:
        raise StudyError(f"cannot write to output folder {out_dir}: {e.strerror or e}") from e
    return out_dir


def build_summary(
    result: StudyResult, params: PlantParams, config: LearnerConfig, preset: str, learner: str
) -> dict[str, Any]:
    """summary.json: run metadata, statistics per trial and across trials."""
    stats = summarise(result.durations_s, params.episode_limit_s, result.seed)
    counters = result.counters if result.counters is not None else np.zeros((1, 4), dtype=np.int64)
    plans = max(int(counters[:, 3].sum()), 1)
    out = {
        "preset": preset,
        "learner": learner,
        "learner_preset": resolve_learner(learner),
        "trials": int(result.durations_s.shape[0]),
        "episodes": int(result.durations_s.shape[1]),
        "seed": result.seed,
        "wall_time_s": round(result.wall_s, 3),
        "threads": result.threads,
        "seeds": list(result.seeds) or [result.seed],
        "memory_bytes": result.memory_bytes,
        "model": {
            # A successor that finds every slot of its row taken evicts the rarest one.
            "slot_evictions": int(counters[:, 0].sum()),
            "trials_with_evictions": int((counters[:, 0] > 0).sum()),
            "planning_sweeps_per_call_mean": round(float(counters[:, 1].sum()) / plans, 3),
            "planning_sweeps_per_call_max": int(counters[:, 2].max()),
        },
        **stats,
        "hold_quality": None if result.hold is None else hold_summary(result.hold, result.recovery_hold),
        "params": asdict(params),
        "learner_config": {k: (int(v) if hasattr(v, "value") else v) for k, v in asdict(config).items()},
    }
    if is_hardware(preset):
        out["hardware_goals"] = goal_lines(out)
    return out


def write_results(
    result: StudyResult, summary: dict[str, Any], config: LearnerConfig, limit_s: float, out_dir: Path
) -> list[Path]:
    """Every output file of a study; returns their paths."""
    try:
        curves_csv = out_dir / "learning_curves.csv"
        with curves_csv.open("w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(["trial", "episode", "duration_s", "alc_s"])
            alc = moving_average(result.durations_s)
            for t, row in enumerate(result.durations_s):
                for e, d in enumerate(row):
                    writer.writerow([t, e, f"{d:.1f}", "" if np.isnan(alc[t, e]) else f"{alc[t, e]:.2f}"])
        npz = out_dir / "learning_curves.npz"
        np.savez_compressed(npz, durations_s=result.durations_s, alc_s=alc, values=result.values,
                            policy=result.policy)
        summary_path = out_dir / "summary.json"
        summary_path.write_text(json.dumps(summary, indent=2) + "\n")
        title = f"{summary['preset']} preset, {summary['learner']} learner"
        figures = write_figures(
            result.durations_s, result.values, result.policy, config, limit_s, out_dir, title
        )
    except OSError as e:
        raise StudyError(f"cannot write results to {out_dir}: {e.strerror or e}") from e
    return [curves_csv, npz, summary_path, *figures]
