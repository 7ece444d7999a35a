"""The hardware goals (issue 17, restated by issue 29) judged on a study's summary: met only where the
95 % interval clears the goal, not the point estimate alone."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Verdict:
    """One goal on one study: the figure, its interval, and whether the interval clears the goal."""

    goal: str
    value: float | None  # None: never (censored)
    ci95: list[float | None]
    met: bool
    text: str  # "67 (66 - 68)" style


def _fmt(x: float | None) -> str:
    return "never" if x is None else f"{x:g}"


def _median_goal(name: str, stat: Any, ci: list[float | None], bound: float) -> Verdict:
    high = ci[1]
    met = stat is not None and high is not None and high <= bound
    return Verdict(f"{name} <= {bound:g}", stat, ci, met, f"{_fmt(stat)} ({_fmt(ci[0])} - {_fmt(high)})")


def hardware_goals(summary: dict[str, Any]) -> list[Verdict]:
    """The four hardware goals of a study summary (summary.json)."""
    across, curve = summary["across_trials"], summary["alc_curves"]["median"]
    first, own = across["first_success"], across["alc_stable_from"]
    never, never_ci = own["fraction_never"], own["fraction_never_ci95"]
    return [
        _median_goal("first success median", first["median"], first["median_ci95"], 20),
        _median_goal("median ALC stable from", curve["stable_from"], curve["bootstrap"]["ci95"], 90),
        _median_goal("per-trial stable-from median", own["median"], own["median_ci95"], 100),
        # Issue 29: at most 5 % never stable, and the upper end of its Wilson interval at most 8 %.
        Verdict("never stable <= 5 %, upper 95 % <= 8 %", never, never_ci,
                never <= 0.05 and never_ci[1] <= 0.08,
                f"{100 * never:.1f} % ({own['count_never']} of {len(summary['trials'])}; "
                f"{100 * never_ci[0]:.1f} - {100 * never_ci[1]:.1f} %)"),
    ]


def goal_lines(summary: dict[str, Any]) -> list[str]:
    """The goals as printable lines, each with 'met' or 'NOT met'."""
    return [f"{v.goal}: {v.text}: {'met' if v.met else 'NOT met'}" for v in hardware_goals(summary)]
