"""Several studies side by side: the comparison table (ratios, bootstrap intervals) and overlaid Fig. 5."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from simulator.errors import StudyError
from simulator.study.runner import StudyResult
from simulator.study.stats import WINDOW, bootstrap_samples, moving_average

_LEVEL = 95.0
PAPER_STABLE_FROM = 230.0  # the paper's Fig. 5: median ALC stable from episode 230 (docs/reproduction.md)


def _interval(samples: NDArray[np.float64]) -> list[float]:
    lo, hi = np.percentile(samples, [50 - _LEVEL / 2, 50 + _LEVEL / 2])
    return [round(float(lo), 3), round(float(hi), 3)]


def compare_rows(
    labels: list[str], presets: list[str], results: list[StudyResult], summaries: list[dict[str, Any]],
    limit_s: list[float],
) -> list[dict[str, Any]]:
    """One row per study; ratios to the first study of the same plant preset (its median ALC stable-from
    over this one's), from paired bootstrap samples when both ran the same seeds and trial count."""
    medians = [
        bootstrap_samples(moving_average(r.durations_s), 50.0, lim, r.seed)
        for r, lim in zip(results, limit_s, strict=True)
    ]
    rows = []
    for i, (label, result, summary) in enumerate(zip(labels, results, summaries, strict=True)):
        ref = presets.index(presets[i])
        across = summary["across_trials"]
        counters = result.counters if result.counters is not None else np.zeros((1, 4), dtype=np.int64)
        plans = max(int(counters[:, 3].sum()), 1)
        curve = summary["alc_curves"]["median"]
        ref_curve = summaries[ref]["alc_curves"]["median"]["stable_from"]
        own = curve["stable_from"]
        ratio = None
        if ref_curve is not None and own is not None and own > 0:
            ratio = round(ref_curve / own, 3)
        rows.append({
            "label": label,
            "trials": int(result.durations_s.shape[0]),
            "seeds": ",".join(str(s) for s in result.seeds),
            "first_success_median": across["first_success"]["median"],
            "first_success_ci95": across["first_success"]["median_ci95"],
            "median_alc_stable_from": own,
            "median_alc_ci95": curve["bootstrap"]["ci95"],
            "best_quarter_stable_from": summary["alc_curves"]["best_quarter_q75"]["stable_from"],
            "own_stable_from_median": across["alc_stable_from"]["median"],
            "own_stable_from_ci95": across["alc_stable_from"]["median_ci95"],
            "never_stable_fraction": round(across["alc_stable_from"]["fraction_never"], 4),
            "never_stable_ci95": across["alc_stable_from"]["fraction_never_ci95"],
            "reference": labels[ref],
            "ratio_to_reference": ratio,
            "ratio_ci95": _interval(medians[ref] / medians[i]) if ref != i else [1.0, 1.0],
            # The paper's own figure as the reference: no draw of our reference run in the ratio.
            "ratio_to_published": (round(PAPER_STABLE_FROM / own, 3) if presets[i] == "paper" and own else None),
            "ratio_to_published_ci95": (_interval(PAPER_STABLE_FROM / np.maximum(medians[i], 1.0))
                                        if presets[i] == "paper" else None),
            "memory_bytes": result.memory_bytes,
            "evictions": int(counters[:, 0].sum()),
            "sweeps_per_plan_mean": round(float(counters[:, 1].sum()) / plans, 2),
            "sweeps_per_plan_max": int(counters[:, 2].max()),
            "wall_s": round(result.wall_s, 2),
        })
    return rows


def write_compare(rows: list[dict[str, Any]], out_dir: Path) -> list[Path]:
    """compare.csv and compare.json."""
    try:
        csv_path = out_dir / "compare.csv"
        with csv_path.open("w", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=list(rows[0]))
            writer.writeheader()
            writer.writerows(rows)
        json_path = out_dir / "compare.json"
        json_path.write_text(json.dumps(rows, indent=2) + "\n")
    except OSError as e:
        raise StudyError(f"cannot write results to {out_dir}: {e.strerror or e}") from e
    return [csv_path, json_path]


def write_overlay(labels: list[str], results: list[StudyResult], limit_s: float, path: Path) -> Path:
    """Fig. 5 of every study in one plot: median ALC and its IQR band per learner."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.2, 4.0))
    for i, (label, result) in enumerate(zip(labels, results, strict=True)):
        alc = moving_average(result.durations_s)[:, WINDOW - 1:]
        episodes = np.arange(WINDOW - 1, result.durations_s.shape[1])
        q25, med, q75 = np.percentile(alc, [25, 50, 75], axis=0)
        color = f"C{i % 10}"
        ax.fill_between(episodes, q25, q75, color=color, alpha=0.18)
        ax.plot(episodes, med, color=color, lw=1.5, label=f"{label} ({result.durations_s.shape[0]} trials)")
    ax.set_xlabel("episode")
    ax.set_ylabel("ALC (s): median and IQR")
    ax.set_ylim(0, limit_s * 1.05)
    ax.set_title("Fig. 5 - median ALC per learner")
    ax.legend(loc="lower right", fontsize=7)
    fig.tight_layout()
    try:
        fig.savefig(path, dpi=120)
    except OSError as e:
        raise StudyError(f"cannot write {path}: {e.strerror or e}") from e
    finally:
        plt.close(fig)
    return path
