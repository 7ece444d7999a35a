"""Re-runs the cheap commands of docs/reproduction.md and compares each figure with the documented one.

    .venv/bin/python scripts/check_reproduction.py [--only NAME ...] [--slow] [--list]

Each check is one command exactly as the page writes it (its `--out` folder replaced by a temporary one), run
from the checkout; its figures are read from the study folder (summary.json, compare.json, learning_curves.npz)
and written in the page's own form. One line per figure: documented, measured, ok or differs; a figure agrees
when every number, rounded half up to the precision the page gives it, is the page's. Exit status 1 if any
figure differs or a command fails. The default checks take about six minutes of both cores in all (each under
three); `--slow` adds the 600-trial and 300-trial ones (4 and 7 minutes). Not a test:
tests/test_reproduction_doc.py runs `trial0`.
"""

from __future__ import annotations

import argparse
import json
import re
import shlex
import subprocess
import sys
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from decimal import ROUND_HALF_UP, Decimal
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "reproduction.md"

Value = float | None  # None: never (not stable, or no success, by the end of the run)


@dataclass
class Study:
    """One command's output folder: its summaries (by sub-folder, '' for a single study) and comparison rows."""

    folder: Path

    @cached_property
    def summaries(self) -> dict[str, dict[str, Any]]:
        if (self.folder / "summary.json").exists():
            return {"": json.loads((self.folder / "summary.json").read_text())}
        return {p.parent.name: json.loads(p.read_text()) for p in sorted(self.folder.glob("*/summary.json"))}

    @cached_property
    def rows(self) -> dict[str, dict[str, Any]]:
        path = self.folder / "compare.json"
        return {r["label"]: r for r in json.loads(path.read_text())} if path.exists() else {}

    def durations(self, run: str = "") -> np.ndarray:
        return np.load(self.folder / run / "learning_curves.npz")["durations_s"]


@dataclass(frozen=True)
class Figure:
    label: str
    documented: str  # as the page writes it (a substring of the page)
    measure: Callable[[Study], list[Value]]


@dataclass(frozen=True)
class Check:
    name: str
    command: str  # as the page writes it
    figures: tuple[Figure, ...]
    slow: bool = False
    seconds: int = field(default=0, compare=False)  # about, on two idle cores


def _never(x: Any, episodes: int = 400) -> Value:
    """A stable-from episode, None for never (the bootstrap writes the run's length for a censored curve)."""
    return None if x is None or float(x) >= episodes else float(x)


def curve(run: str, key: str) -> Callable[[Study], list[Value]]:
    """A curve-wise statistic with its 80 % and 95 % bootstrap intervals."""
    def get(s: Study) -> list[Value]:
        c = s.summaries[run]["alc_curves"][key]
        ci80, ci95 = c["bootstrap"]["ci80"], c["bootstrap"]["ci95"]
        return [_never(c["stable_from"]), *map(_never, ci80), *map(_never, ci95)]
    return get


def per_trial(run: str, key: str, ci: bool = False, never: bool = False) -> Callable[[Study], list[Value]]:
    """A per-trial figure: median [IQR], optionally the median's 95 % interval and the share never reached (%)."""
    def get(s: Study) -> list[Value]:
        q = s.summaries[run]["across_trials"][key]
        out: list[Value] = [q["median"], q["q25"], q["q75"]]
        return out + (list(q["median_ci95"]) if ci else []) + ([100 * q["fraction_never"]] if never else [])
    return get


def summary(run: str, *path: str | int, scale: float = 1.0) -> Callable[[Study], list[Value]]:
    """One number of a summary.json (or a list of them), scaled."""
    def get(s: Study) -> list[Value]:
        value: Any = s.summaries[run]
        for key in path:
            value = value[key]
        return [None if v is None else scale * v for v in (value if isinstance(value, list) else [value])]
    return get


def row(label: str, *keys: str, scale: dict[str, float] | None = None) -> Callable[[Study], list[Value]]:
    """Numbers of one comparison row (compare.json), in order; a list value contributes all its numbers."""
    def get(s: Study) -> list[Value]:
        out: list[Value] = []
        for key in keys:
            v = s.rows[label][key]
            k = (scale or {}).get(key, 1.0)
            if isinstance(v, list):
                out.extend(k * x for x in v)
            else:
                out.append(k * v)
        return out
    return get


def hardware_row(run: str) -> Callable[[Study], list[Value]]:
    """A hardware-preset row of the page: trials with a first success, its median [IQR] (95 %), the late success
    rate with its Wilson interval (%), and the share of trials whose ALC is never stable (%)."""
    def get(s: Study) -> list[Value]:
        m = s.summaries[run]
        first = m["across_trials"]["first_success"]
        trials = len(m["trials"])
        reached = [trials - first["count_never"], trials, first["median"]]
        if first["median"] is not None:
            reached += [first["q25"], first["q75"], *first["median_ci95"]]
        rate = [100 * m["success_rate_last_50"]]
        if first["median"] is not None:
            rate += [100 * x for x in m["success_rate_last_50_ci95"]]
        return reached + rate + [100 * m["across_trials"]["alc_stable_from"]["fraction_never"]]
    return get


def goals_row(run: str) -> Callable[[Study], list[Value]]:
    """The four hardware goals as `python -m simulator.study.report` prints them, then hold RMS and travel."""
    def get(s: Study) -> list[Value]:
        m = s.summaries[run]
        first, own = m["across_trials"]["first_success"], m["across_trials"]["alc_stable_from"]
        med = m["alc_curves"]["median"]
        hold = m["hold_quality"]
        mine, rec = hold["learner"], hold["recovery"]
        rms, travel = "rms_depth_error_mm", "actuator_travel_deg_per_min"
        return [first["median"], *first["median_ci95"],
                _never(med["stable_from"]), *map(_never, med["bootstrap"]["ci95"]),
                own["median"], *own["median_ci95"],
                100 * own["fraction_never"], own["count_never"], len(m["trials"]),
                *(100 * x for x in own["fraction_never_ci95"]),
                mine[rms]["median"], mine[rms]["q25"], mine[rms]["q75"], rec[rms]["median"],
                mine[travel]["median"], rec[travel]["median"]]
    return get


def mean_episode(run: str) -> Callable[[Study], list[Value]]:
    return lambda s: [float(s.durations(run).mean())]


S = "python -m simulator study "  # every command below is a study of the page, written as the page writes it
_P100 = "--trials 100 --episodes 400 --out study-out/"
_FDEPTH = "shared-z20-bins7-fdepth-term100-vpen1"  # `hardware` until issue 43 (docs/reproduction.md)
_ROW_KEYS = ("first_success_median", "first_success_ci95", "median_alc_stable_from", "median_alc_ci95",
             "own_stable_from_median", "own_stable_from_ci95", "never_stable_fraction")
_ROW_600 = ("trials", "median_alc_stable_from", "median_alc_ci95", "never_stable_fraction", "never_stable_ci95",
            "ratio_to_reference", "ratio_ci95", "ratio_to_published", "ratio_to_published_ci95")
_PERCENT = {"never_stable_fraction": 100.0, "never_stable_ci95": 100.0}


def _first3(measure: Callable[[Study], list[Value]]) -> Callable[[Study], list[Value]]:
    return lambda s: measure(s)[:3]


CHECKS: tuple[Check, ...] = (
    Check("trial0", S + "--preset paper --learner paper --trials 1 --episodes 400 --out study-out/paper-trial0", (
        Figure("trial 0's first success", "episode 20", summary("", "trials", 0, "first_success")),
    ), seconds=3),
    Check("paper", S + "--preset paper --learner paper " + _P100 + "paper", (
        Figure("median ALC stable from (80 %, 95 %)", "**229** | 218 - 252 | 211 - 281", curve("", "median")),
        Figure("best quarter (80 %, 95 %)", "**124** | 108 - 138 | 104 - 157", curve("", "best_quarter_q75")),
        Figure("worst quarter (80 %, 95 %)", "399 | 324 - never | 318 - never", curve("", "worst_quarter_q25")),
        Figure("first success per trial", "14.5 [10 - 20]", per_trial("", "first_success")),
        Figure("last failure per trial", "247.5 [168 - 346]", per_trial("", "last_failure")),
        Figure("own ALC stable from per trial",
               "297.5 [218 - 396] (median 265.5 - 323); 24 % of trials never stable",
               per_trial("", "alc_stable_from", ci=True, never=True)),
        Figure("success rate, episodes 350-399", "99.2 %", summary("", "success_rate_last_50", scale=100)),
        Figure("memory_bytes", "8 080", summary("", "memory_bytes")),
    ), seconds=20),
    Check("actuator3", S + "--preset paper --learner actuator3 " + _P100 + "actuator3", (
        Figure("median ALC stable from (80 %)", "**115** (112 - 129)", _first3(curve("", "median"))),
        Figure("best quarter (80 %)", "89 (86 - 98)", _first3(curve("", "best_quarter_q75"))),
        Figure("memory_bytes", "31 304", summary("", "memory_bytes")),
    ), seconds=25),
    Check("rmax", S + "--preset paper --learner rmax " + _P100 + "rmax", (
        Figure("median ALC stable from (80 %)", "147 (134 - 172)", _first3(curve("", "median"))),
        Figure("best quarter (80 %)", "102 (100 - 116)", _first3(curve("", "best_quarter_q75"))),
    ), seconds=20),
    Check("ties", S + "--preset paper --compare paper,rmax --ties per-step " + _P100 + "ties", (
        Figure("paper, per-step ties: median ALC stable from", "223 (174 - 285)",
               row("paper/paper", "median_alc_stable_from", "median_alc_ci95")),
        Figure("rmax, per-step ties: median ALC stable from", "216 (196 - 237)",
               row("paper/rmax", "median_alc_stable_from", "median_alc_ci95")),
        Figure("rmax, per-step ties: ratio to paper", "1.03 (0.80 - 1.36)",
               row("paper/rmax", "ratio_to_reference", "ratio_ci95")),
    ), seconds=40),
    Check("evictions", S + "--preset paper --learner actuator3 --trials 30 --episodes 400 --out "
          "study-out/actuator3-30", (
        Figure("actuator3 slot evictions", "158 evictions, in 28 of 30 trials",
               lambda s: [*summary("", "model", "slot_evictions")(s), *summary("", "model", "trials_with_evictions")(s),
                          len(s.summaries[""]["trials"])]),
    ), seconds=8),
    Check("goal-paper", S + "--preset paper --compare paper,shared --seeds 0-2 " + _P100 + "goal-paper", (
        Figure("paper, 300 trials: median ALC stable from (80 %, 95 %)", "**208** | 202.8 - 224 | 186 - 231",
               curve("paper_paper", "median")),
        Figure("paper, 300 trials: best quarter (80 %, 95 %)", "**111** | 107 - 121 | 105 - 124",
               curve("paper_paper", "best_quarter_q75")),
        Figure("paper, 300 trials: first success per trial", "17 [11 - 20] | | 16 - 18",
               per_trial("paper_paper", "first_success", ci=True)),
        Figure("paper, 300 trials: own ALC stable from", "295 [205.5 - 384]; 21.7 % never stable | | 277.5 - 312",
               lambda s: [*per_trial("paper_paper", "alc_stable_from", never=True)(s),
                          *summary("paper_paper", "across_trials", "alc_stable_from", "median_ci95")(s)]),
        Figure("paper row", "17 (16 - 18) | 208 (186 - 231) | 295 (277.5 - 312) | 21.7 %",
               row("paper/paper", *_ROW_KEYS, scale=_PERCENT)),
        Figure("shared row", "1 (1 - 1) | **56 (56 - 57)** | 57 (56 - 57) | 0 % | **3.71 (3.32 - 4.13)** | 1 204",
               row("paper/shared", *_ROW_KEYS, "ratio_to_reference", "ratio_ci95", "memory_bytes", scale=_PERCENT)),
    ), seconds=150),
    Check("hardware-paper", S + "--preset hardware --learner paper " + _P100 + "hardware-paper", (
        Figure("paper, 0.1/0.04", "0 of 100 | never | 0.0 % | 100 %", hardware_row("hardware_paper_0.1_0.04")),
        Figure("paper, 0.15/0.03", "1 of 100 | never | 0.0 % | 100 %", hardware_row("hardware_paper_0.15_0.03")),
        Figure("paper, 0.1/0.04: mean episode", "5.4 s on average", mean_episode("hardware_paper_0.1_0.04")),
        Figure("paper, 0.15/0.03: mean episode", "5.4 s on average", mean_episode("hardware_paper_0.15_0.03")),
    ), seconds=20),
    Check("hardware-actuator3", S + "--preset hardware --learner actuator3 " + _P100 + "hardware-actuator3", (
        Figure("actuator3, 0.1/0.04", "100 of 100 | 75 [66 - 85.25] (72.5 - 79) | 75.2 % (73.9 - 76.3) | 99 %",
               hardware_row("hardware_actuator3_0.1_0.04")),
        Figure("actuator3, 0.15/0.03", "100 of 100 | 77 [69.75 - 93.25] (74 - 84) | 83.0 % (81.9 - 84.0) | 99 %",
               hardware_row("hardware_actuator3_0.15_0.03")),
    ), seconds=60),
    Check("goal-paper-600", S + "--preset paper --compare paper,shared --seeds 0-5 " + _P100 + "goal-paper-600", (
        Figure("paper/paper, 600 trials",
               "| paper/paper | 600 | 189 (163 - 206) | 21.8 % (18.7 - 25.3) | 1 (1 - 1) | 1.217 (1.117 - 1.411) |",
               row("paper/paper", *_ROW_600, scale=_PERCENT)),
        Figure("paper/shared, 600 trials",
               "| paper/shared | 600 | 56 (56 - 57) | 0.0 % (0.0 - 0.6) | 3.375 (2.911 - 3.679) | "
               "4.107 (4.035 - 4.107) |",
               row("paper/shared", *_ROW_600, scale=_PERCENT)),
    ), slow=True, seconds=240),
    Check("robust-modelled", S + f"--preset hardware --learner {_FDEPTH} --seeds 40-42 " + _P100 + "robust-modelled", (
        Figure("hardware, as modelled, 0.15/0.03",
               "12 (12 - 12) | 64 (64 - 65) | 64.5 (64 - 65) | 0.7 % (2 of 300; 0.2 - 2.4 %) | 3.32 [1.35 - 9.65] / "
               "0.11 | 1260 / 600.9", goals_row(f"hardware_{_FDEPTH}_0.15_0.03")),
        Figure("hardware, as modelled, 0.1/0.04",
               "11 (10 - 11) | 63 (63 - 64) | 65 (63.5 - 66) | 1.3 % (4 of 300; 0.5 - 3.4 %) | 2.71 [1.12 - 5.7] / "
               "0.11 | 1260 / 600.9", goals_row(f"hardware_{_FDEPTH}_0.1_0.04")),
    ), slow=True, seconds=430),
)

# A number, or "never" standing for one (not the words "never stable").
_NUMBER = re.compile(r"never(?! stable)|\d+(?: \d{3})*(?:\.\d+)?")


def documented_numbers(text: str) -> list[tuple[Value, int]]:
    """Each number of a documented figure with its decimals; None for 'never'."""
    out: list[tuple[Value, int]] = []
    for token in _NUMBER.findall(text):
        if token == "never":
            out.append((None, 0))
        else:
            plain = token.replace(" ", "")
            out.append((float(plain), len(plain.partition(".")[2])))
    return out


def _rounded(value: float, decimals: int) -> Decimal:
    """The value as the page would print it: rounded half up from its shortest repr (3.315 -> 3.32)."""
    return Decimal(repr(float(value))).quantize(Decimal(1).scaleb(-decimals), rounding=ROUND_HALF_UP)


def agrees(documented: str, measured: Sequence[Value]) -> bool:
    """Every number equal to the documented one at the documented precision (never only with never)."""
    expected = documented_numbers(documented)
    if len(expected) != len(measured):
        return False
    for (want, decimals), got in zip(expected, measured, strict=True):
        if want is None or got is None:
            if want is not got:
                return False
        elif _rounded(got, decimals) != _rounded(want, decimals):
            return False
    return True


def render(documented: str, measured: Sequence[Value]) -> str:
    """The measured numbers in the documented figure's form (same decimals and grouping)."""
    expected = documented_numbers(documented)
    if len(expected) != len(measured):
        return " ".join("never" if v is None else f"{v:g}" for v in measured)
    values = iter(zip(expected, measured, strict=True))

    def one(match: re.Match[str]) -> str:
        (_, decimals), got = next(values)
        if got is None:
            return "never"
        text = str(_rounded(got, decimals))
        if " " in match.group():  # thousands grouped as the page groups them: 8 080
            whole, dot, fraction = text.partition(".")
            text = f"{int(whole):,}".replace(",", " ") + dot + fraction
        return text
    return _NUMBER.sub(one, documented)


def _plain(text: str) -> str:
    return text.replace("**", "").replace(" | | ", "; ").replace(" | ", "; ").strip("| ")


def run_check(check: Check, scratch: Path) -> bool:
    """Runs the check's command into scratch, prints one line per figure; True if every figure agrees."""
    words = shlex.split(check.command)
    out = scratch / check.name
    words[words.index("--out") + 1] = str(out)
    words[0] = sys.executable
    done = subprocess.run(words, cwd=ROOT, capture_output=True, text=True)
    if done.returncode != 0:
        last = (done.stderr.strip().splitlines() or ["no message"])[-1]
        print(f"{check.name}: the command failed ({done.returncode}): {last}", flush=True)
        return False
    study, ok = Study(out), True
    for figure in check.figures:
        try:
            measured = figure.measure(study)
        except (KeyError, IndexError, OSError, TypeError, ValueError) as e:
            print(f"{check.name}: {figure.label}: documented {_plain(figure.documented)}, "
                  f"not measured ({e!r}): differs")
            ok = False
            continue
        same = agrees(figure.documented, measured)
        ok &= same
        print(f"{check.name}: {figure.label}: documented {_plain(figure.documented)}, measured "
              f"{_plain(render(figure.documented, measured))}: {'ok' if same else 'differs'}", flush=True)
    return ok


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--only", action="append", metavar="NAME", help="run this check (repeatable)")
    parser.add_argument("--slow", action="store_true", help="also the 600- and 300-trial checks")
    parser.add_argument("--list", action="store_true", help="list the checks and their commands")
    args = parser.parse_args(argv)
    names = {c.name for c in CHECKS}
    unknown = set(args.only or ()) - names
    if unknown:
        parser.error(f"unknown check {', '.join(sorted(unknown))}; choose from {', '.join(sorted(names))}")
    chosen = [c for c in CHECKS if (c.name in args.only if args.only else args.slow or not c.slow)]
    if args.list:
        for c in CHECKS:
            print(f"{c.name}{' (slow)' if c.slow else ''}, about {c.seconds} s: {c.command}")
        return 0
    with tempfile.TemporaryDirectory(prefix="check-reproduction-") as scratch:
        results = [run_check(c, Path(scratch)) for c in chosen]
    bad = [c.name for c, ok in zip(chosen, results, strict=True) if not ok]
    print(f"{len(chosen) - len(bad)} of {len(chosen)} checks agree with docs/reproduction.md"
          + (f"; differ: {', '.join(bad)}" if bad else ""))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
