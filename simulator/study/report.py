"""Markdown tables for the docs from study folders: `python -m simulator.study.report DIR [DIR ...]`.

Each DIR is a `dive study --out` folder (one summary.json, or one per run in sub-folders, with compare.json).
Hardware-preset studies get the goals table (met only where the interval clears the goal) and the hold
quality beside the recovery controller's; comparisons get the ratio table with the ratio to the paper's 230.
"""

from __future__ import annotations

import json
import sys
from pathlib import Path
from typing import Any

from simulator.parameters import is_hardware
from simulator.study.goals import hardware_goals


def _summaries(folder: Path) -> list[dict[str, Any]]:
    paths = [folder / "summary.json"] if (folder / "summary.json").exists() else sorted(folder.glob("*/summary.json"))
    return [json.loads(p.read_text()) for p in paths]


def _region(summary: dict[str, Any]) -> str:
    config = summary["learner_config"]
    return f"{config['z_tol_m']:g} m / {config['zdot_tol_mps']:g} m/s"


def _med(block: dict[str, Any] | None, key: str) -> str:
    if not block or block.get(key, {}).get("median") is None:
        return "-"
    q = block[key]
    return f"{q['median']:g} [{q['q25']:g} - {q['q75']:g}]"


def goals_table(summaries: list[dict[str, Any]]) -> str:
    """One row per hardware study: the four goals, then the hold's oscillation, offset and travel against the recovery
    controller's on the same plants at the same plant time."""
    head = ("| study | region | trials | first success (<= 20) | median ALC stable from (<= 90) | per-trial stable "
            "from, median (<= 100) | never stable (<= 5 %, Wilson upper <= 8 %) | hold oscillation RMS mm: learner / "
            "recovery | offset mm: learner / recovery | travel deg/min: learner / recovery |")
    rows = [head, "|" + "---|" * 10]
    for s in summaries:
        cells = [f"{v.text}: {'met' if v.met else '**not met**'}" for v in hardware_goals(s)]
        hold = s.get("hold_quality") or {}
        mine, rec = hold.get("learner"), hold.get("recovery")
        rows.append(
            f"| {s['preset']}/{s['learner']} | {_region(s)} | {len(s['trials'])} | " + " | ".join(cells)
            + f" | {_med(mine, 'oscillation_rms_mm')} / {_med(rec, 'oscillation_rms_mm')}"
            + f" | {_med(mine, 'offset_mm')} / {_med(rec, 'offset_mm')}"
            + f" | {_med(mine, 'actuator_travel_deg_per_min')} / {_med(rec, 'actuator_travel_deg_per_min')} |")
    return "\n".join(rows)


def compare_table(rows: list[dict[str, Any]]) -> str:
    """A comparison (compare.json): median ALC stable-from, ratio to the first learner and to the paper's 230."""
    def pair(value: Any, ci: Any) -> str:
        if value is None:
            return "-"
        return f"{value:g} ({ci[0]:g} - {ci[1]:g})" if ci else f"{value:g}"

    out = ["| learner | trials | median ALC stable from | never stable (Wilson 95 %) | ratio to the first | "
           "ratio to the paper's 230 |", "|" + "---|" * 6]
    for r in rows:
        ci = r["never_stable_ci95"]
        never = f"{100 * r['never_stable_fraction']:.1f} % ({100 * ci[0]:.1f} - {100 * ci[1]:.1f})"
        out.append(f"| {r['label']} | {r['trials']} | {pair(r['median_alc_stable_from'], r['median_alc_ci95'])} | "
                   f"{never} | {pair(r['ratio_to_reference'], r['ratio_ci95'])} | "
                   f"{pair(r.get('ratio_to_published'), r.get('ratio_to_published_ci95'))} |")
    return "\n".join(out)


def report(folder: Path) -> str:
    """The tables of one study folder."""
    parts = []
    if (folder / "compare.json").exists():
        parts.append(compare_table(json.loads((folder / "compare.json").read_text())))
    hardware = [s for s in _summaries(folder) if is_hardware(s["preset"])]
    if hardware:
        parts.append(goals_table(hardware))
    if not parts:
        raise FileNotFoundError(f"{folder} holds no study results (summary.json or compare.json)")
    return "\n\n".join(parts)


def main(argv: list[str] | None = None) -> int:
    folders = [Path(a) for a in (sys.argv[1:] if argv is None else argv)]
    if not folders:
        print("usage: python -m simulator.study.report DIR [DIR ...]", file=sys.stderr)
        return 2
    try:
        for folder in folders:
            print(f"<!-- python -m simulator.study.report {folder} -->\n{report(folder)}\n")
    except (OSError, ValueError, KeyError) as e:
        print(f"report: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
