"""Measured against predicted depth, window by window, as a PNG (matplotlib, no display needed)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from simulator.fit.estimate import FitResult


def plot_fit(result: FitResult, path: Path, max_windows: int = 6) -> None:
    """The longest windows' measured depth, the fitted plant's prediction and their difference."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    windows = result.windows
    lengths = windows.ends - windows.starts
    chosen = sorted(np.argsort(lengths)[::-1][:max_windows])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(10, 6), sharex=True, height_ratios=(3, 1))
    offset = 0.0
    for number, w in enumerate(chosen):
        span = slice(windows.starts[w], windows.ends[w])
        t = windows.t_s[span] - windows.t_s[span][0] + offset
        measured, predicted = windows.depth_m[span], result.hull.predicted_m[span]
        top.plot(t, 100 * measured, ".", ms=2, color="tab:blue", label="measured" if number == 0 else None)
        top.plot(t, 100 * predicted, "-", lw=1.2, color="tab:orange", label="fitted plant" if number == 0 else None)
        bottom.plot(t, 1000 * (measured - predicted), ".", ms=2, color="tab:gray")
        offset = float(t[-1]) + 1.0
    top.invert_yaxis()  # depth grows downward
    top.set_ylabel("depth, cm")
    top.set_title(f"dive fit: {len(chosen)} of {windows.count} windows, residual RMS "
                  f"{1000 * result.residual_rms_m:.2f} mm")
    top.legend(loc="best")
    bottom.set_ylabel("residual, mm")
    bottom.set_xlabel("agent time within the windows shown, s")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
