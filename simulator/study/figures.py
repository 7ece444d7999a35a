"""PNG figures of a study in the style of the paper's Figs. 4-7 (matplotlib, Agg backend)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; no display on the study machine

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from numpy.typing import NDArray  # noqa: E402

from learning import LearnerConfig  # noqa: E402
from learning.acting import TIED  # noqa: E402
from simulator.study.stats import WINDOW, moving_average  # noqa: E402

_DPI = 120


def _grid(per_state: NDArray[np.float64], config: LearnerConfig) -> NDArray[np.float64]:
    """[trials, S] -> mean over trials and actuator bins as [z cell, zdot cell]."""
    live = per_state[:, :-1].reshape(-1, config.actuator_bins, config.z_cells, config.zdot_cells)
    return live.mean(axis=(0, 1))


def _heatmap(grid: NDArray[np.float64], config: LearnerConfig, title: str, label: str, path: Path,
             cmap: str) -> None:
    fig, ax = plt.subplots(figsize=(5.2, 4.2))
    extent = (-config.zdot_tol_mps, config.zdot_tol_mps, config.z_tol_m, -config.z_tol_m)
    image = ax.imshow(grid, extent=extent, aspect="auto", cmap=cmap, interpolation="nearest")
    ax.set_xlabel("velocity z' (m/s, positive down)")
    ax.set_ylabel("depth error z - z_d (m, positive down)")
    ax.set_title(title)
    fig.colorbar(image, ax=ax, label=label)
    fig.tight_layout()
    fig.savefig(path, dpi=_DPI)
    plt.close(fig)


def write_figures(
    durations_s: NDArray[np.float64],
    values: NDArray[np.float64],
    policy: NDArray[np.int8],
    config: LearnerConfig,
    limit_s: float,
    out_dir: Path,
    title: str,
) -> list[Path]:
    """fig4 one learning curve, fig5 median and IQR of the ALC, fig6 mean values, fig7 mean policy."""
    paths = [out_dir / f"fig{n}_{name}.png" for n, name in
             ((4, "learning_curve"), (5, "alc_median_iqr"), (6, "value_function"), (7, "policy"))]
    alc = moving_average(durations_s)
    episodes = np.arange(durations_s.shape[1])

    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    ax.plot(episodes, durations_s[0], color="black", lw=0.7, label="learning curve (trial 0)")
    ax.plot(episodes, alc[0], color="red", lw=1.6, label="moving average, 50 episodes")
    ax.set_xlabel("episode")
    ax.set_ylabel("time in learning region (s)")
    ax.set_ylim(0, limit_s * 1.05)
    ax.set_title(f"Fig. 4 - {title}")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(paths[0], dpi=_DPI)
    plt.close(fig)

    first = WINDOW - 1  # the trailing average exists from the 50th episode on
    q25, med, q75 = np.percentile(alc[:, first:], [25, 50, 75], axis=0)
    fig, ax = plt.subplots(figsize=(6.4, 3.6))
    ax.fill_between(episodes[first:], q25, q75, color="tab:blue", alpha=0.3, label="IQR of ALC")
    ax.plot(episodes[first:], med, color="tab:blue", lw=1.6, label="median ALC")
    ax.set_xlabel("episode")
    ax.set_ylabel("ALC (s)")
    ax.set_ylim(0, limit_s * 1.05)
    ax.set_title(f"Fig. 5 - {title}, {durations_s.shape[0]} trials")
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(paths[1], dpi=_DPI)
    plt.close(fig)

    _heatmap(_grid(values, config), config, f"Fig. 6 - mean value function ({values.shape[0]} trials)",
             "v(s)", paths[2], "viridis")
    share = np.where(policy == TIED, 0.5, policy).astype(float)  # a tie drawn per step is half a2
    _heatmap(_grid(share, config), config,
             f"Fig. 7 - mean policy ({policy.shape[0]} trials)", "share choosing a2 (more volume)",
             paths[3], "coolwarm")
    return paths
