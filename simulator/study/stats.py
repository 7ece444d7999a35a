"""Statistics of a study: learning curves, their 50-episode moving average, stable episodes, bootstrap."""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

WINDOW = 50  # paper V-A: the ALC is the moving average of the LC over 50 episodes
BOOTSTRAP_SAMPLES = 1000
_EPS_S = 1e-6
_Z95 = 1.959963984540054  # two-sided 95 % normal quantile


def wilson_interval(successes: int, n: int, z: float = _Z95) -> list[float]:
    """Wilson score interval of a proportion (95 % by default): honest at 0, 1 and small n."""
    if n <= 0:
        return [0.0, 1.0]
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z / (1 + z * z / n) * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return [round(max(0.0, float(centre - half)), 5), round(min(1.0, float(centre + half)), 5)]


def moving_average(durations_s: NDArray[np.float64], window: int = WINDOW) -> NDArray[np.float64]:
    """Trailing moving average along the last axis: entry e averages episodes e-window+1..e; NaN before."""
    x = np.asarray(durations_s, dtype=float)
    out = np.full(x.shape, np.nan)
    if x.shape[-1] < window:
        return out
    c = np.cumsum(x, axis=-1)
    c = np.concatenate([np.zeros((*x.shape[:-1], 1)), c], axis=-1)
    out[..., window - 1:] = (c[..., window:] - c[..., :-window]) / window
    return out


def stable_from(curve: NDArray[np.float64], limit_s: float) -> int | None:
    """First episode from which the curve stays at the limit to the end; None if it ends below it."""
    ok = np.nan_to_num(curve, nan=-1.0) >= limit_s - _EPS_S
    if not ok[-1]:
        return None
    bad = np.nonzero(~ok)[0]
    return int(bad[-1] + 1) if bad.size else 0


def _stable_rows(ok: NDArray[np.bool_]) -> NDArray[np.float64]:
    """First index from which every entry of a row is True; NaN where the row ends False."""
    n = ok.shape[-1]
    last_bad = n - 1 - np.argmax(~ok[..., ::-1], axis=-1)
    result = np.where(ok.all(axis=-1), 0, last_bad + 1).astype(float)
    return np.where(ok[..., -1], result, np.nan)


def per_trial(durations_s: NDArray[np.float64], limit_s: float) -> list[dict[str, int | None]]:
    """First success, last failure and ALC-stable episode of each trial (episodes counted from 0)."""
    alc = moving_average(durations_s)
    rows = []
    for trial, row in enumerate(durations_s):
        success = np.nonzero(row >= limit_s - _EPS_S)[0]
        failure = np.nonzero(row < limit_s - _EPS_S)[0]
        rows.append({
            "trial": trial,
            "first_success": int(success[0]) if success.size else None,
            "last_failure": int(failure[-1]) if failure.size else None,
            "alc_stable_from": stable_from(alc[trial], limit_s),
        })
    return rows


def _spread(values: list[int | None], never: float, censored: bool = True) -> dict[str, Any]:
    """Quartiles over trials with the trials that never got there censored at `never`, not dropped.

    A quartile that lands on a censored trial is reported as None ("never"), since its true value is
    only known to lie beyond the run.
    """
    x = np.array([never if v is None else v for v in values], dtype=float)
    n_never = sum(v is None for v in values) if censored else 0
    count_never = sum(v is None for v in values)
    out: dict[str, Any] = {
        "censored_at": never, "fraction_never": count_never / len(values),
        "count_never": count_never, "fraction_never_ci95": wilson_interval(count_never, len(values)),
    }
    for key, q in (("q25", 25.0), ("median", 50.0), ("q75", 75.0)):
        value = float(np.percentile(x, q))
        out[key] = None if (n_never and value >= never) else value
    return out


def bootstrap_median(values: list[int | None], never: float, seed: int, level: float = 95.0) -> list[float | None]:
    """Percentile bootstrap interval of the median over trials, never-trials censored at `never`."""
    x = np.array([never if v is None else v for v in values], dtype=float)
    rng = np.random.default_rng(seed)
    medians = np.median(x[rng.integers(0, x.size, size=(BOOTSTRAP_SAMPLES, x.size))], axis=1)
    lo, hi = np.percentile(medians, [50 - level / 2, 50 + level / 2])
    return [float(lo), None if (never >= 0 and hi >= never) else float(hi)]


def curve_statistic(alc: NDArray[np.float64], q: float, limit_s: float) -> int | None:
    """Episode from which the q-th percentile (over trials) of the ALC reaches the limit and stays."""
    return stable_from(np.percentile(alc, q, axis=0), limit_s)


def bootstrap_samples(alc: NDArray[np.float64], q: float, limit_s: float, seed: int) -> NDArray[np.float64]:
    """curve_statistic of BOOTSTRAP_SAMPLES resamples of the trials; never-settling samples count as the
    last episode + 1. The same seed and trial count draw the same resamples, so two studies on the same
    seeds give paired samples (their ratio is a paired bootstrap).

    No percentile is computed: an ALC never exceeds the limit, so the q-th percentile (linear
    interpolation between sorted values lo and lo + 1) is at the limit exactly when value lo is, i.e. when
    at least n - lo trials of the resample are. Counting trials at the limit is one matrix product.
    """
    rng = np.random.default_rng(seed)
    n_trials, n_episodes = alc.shape
    valid = alc[:, WINDOW - 1:] if n_episodes >= WINDOW else alc
    at_limit = (np.nan_to_num(valid, nan=-1.0) >= limit_s - _EPS_S).astype(np.float64)
    lo = int(np.floor(q / 100.0 * (n_trials - 1)))
    stats = np.empty(BOOTSTRAP_SAMPLES)
    for start in range(0, BOOTSTRAP_SAMPLES, 100):
        idx = rng.integers(0, n_trials, size=(min(100, BOOTSTRAP_SAMPLES - start), n_trials))
        rows = len(idx)
        flat = (idx + n_trials * np.arange(rows)[:, None]).ravel()
        picks = np.bincount(flat, minlength=rows * n_trials).reshape(rows, n_trials).astype(np.float64)
        ok = picks @ at_limit >= n_trials - lo
        stats[start:start + len(idx)] = _stable_rows(ok) + (n_episodes - valid.shape[1])
    stats[np.isnan(stats)] = n_episodes
    return stats


def bootstrap_interval(
    alc: NDArray[np.float64], q: float, limit_s: float, seed: int, levels: tuple[float, ...] = (80.0, 95.0)
) -> dict[str, Any]:
    """Bootstrap over trials of curve_statistic; samples that never settle count as the last episode + 1."""
    stats = bootstrap_samples(alc, q, limit_s, seed)
    out: dict[str, Any] = {"samples": BOOTSTRAP_SAMPLES, "fraction_never": float(np.mean(stats >= alc.shape[1]))}
    for level in levels:
        lo, hi = np.percentile(stats, [50 - level / 2, 50 + level / 2])
        out[f"ci{int(level)}"] = [float(lo), float(hi)]
    return out


def summarise(durations_s: NDArray[np.float64], limit_s: float, seed: int) -> dict[str, Any]:
    """The summary.json statistics (without run metadata)."""
    alc = moving_average(durations_s)
    trials = per_trial(durations_s, limit_s)
    n_episodes = durations_s.shape[1]
    # Never reached: censored at the end of the run (first success, stable from); a trial that never
    # failed has its last failure before episode 0.
    never = {"first_success": float(n_episodes), "last_failure": -1.0, "alc_stable_from": float(n_episodes)}
    late = durations_s[:, -WINDOW:] >= limit_s - _EPS_S
    curve = {}
    for label, q in (("median", 50.0), ("best_quarter_q75", 75.0), ("worst_quarter_q25", 25.0)):
        curve[label] = {
            "stable_from": curve_statistic(alc, q, limit_s),
            "bootstrap": bootstrap_interval(alc, q, limit_s, seed),
        }
    return {
        "convention": (
            f"ALC = trailing {WINDOW}-episode moving average of the episode durations (entry e averages "
            f"episodes e-{WINDOW - 1}..e, episodes counted from 0); 'stable_from' is the first episode from "
            f"which a curve stays at {limit_s:g} s to the end of the run"
        ),
        "across_trials": {
            key: {
                **_spread([t[key] for t in trials], never[key], censored=key != "last_failure"),
                "median_ci95": bootstrap_median([t[key] for t in trials], never[key], seed),
            }
            for key in ("first_success", "last_failure", "alc_stable_from")
        },
        "alc_curves": curve,
        "success_rate_last_50": float(np.mean(late)),
        # Episodes of one trial are not independent: the Wilson interval over episodes is a floor on the spread.
        "success_rate_last_50_ci95": wilson_interval(int(late.sum()), int(late.size)),
        "trials": trials,
    }
