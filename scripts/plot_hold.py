"""A learned hold, plotted: true depth error and commanded gear angle over 60 s of a late successful episode, one
panel per learner (issue 43 item 5; docs/learners-hold.md).

    .venv/bin/python scripts/plot_hold.py [--seed 61] [--trial 0] [--episodes 200] [--out docs/figures/hold.png]
        [--runs hardware/hardware,hardware/fine41,paper/paper]

Each run replays one study trial with simulator/study/kernel.py's replay_trial (the study's own loop and streams),
recording every step, and plots the window 200-260 s of its last successful episode; the panel's title gives that
window's RMS about its mean, its offset and the stepper's travel. Not a test.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from learning import n_states  # noqa: E402
from learning.config import kernel_spec  # noqa: E402
from learning.presets import learner_preset  # noqa: E402
from simulator.parameters import kernel_params, preset  # noqa: E402
from simulator.plant.episode import E_CMD, E_MOTOR, E_Z, episode_steps  # noqa: E402
from simulator.study.kernel import S_ENV, StepRecord, TrialArrays, trial_kernels  # noqa: E402
from simulator.study.runner import trial_streams  # noqa: E402

WINDOW_S = (200.0, 260.0)
S_Z, S_CMD, S_MOTOR = S_ENV, S_ENV + 1, S_ENV + 2


def hold_trace(preset_name: str, learner: str, seed: int, trial: int, episodes: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
    """(time s, depth error m, commanded angle deg, episode) over WINDOW_S of the trial's last successful episode."""
    params, config = preset(preset_name), learner_preset(learner)
    spec, lspec = kernel_params(params), kernel_spec(config)
    out = TrialArrays.zeros((), episodes, n_states(config))
    record = StepRecord(np.array([E_Z, E_CMD, E_MOTOR]), np.full((episodes, episode_steps(spec), S_ENV + 3), np.nan))
    trial_kernels(params).replay_trial(*trial_streams(seed, trial), params.target_depth_m, spec, lspec, out, record)
    held = np.nonzero(out.durations_s >= params.episode_limit_s - 1e-6)[0]
    if held.size == 0:
        raise SystemExit(f"{preset_name}/{learner}: trial {trial} of seed {seed} never held 300 s")
    episode = int(held[-1])
    t_s = (np.arange(episode_steps(spec)) + 1) * params.control_period_s
    keep = (t_s >= WINDOW_S[0]) & (t_s < WINDOW_S[1])
    rows = record.rows[episode][keep]
    return t_s[keep], rows[:, S_Z] - params.target_depth_m, rows[:, S_CMD], episode


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", default="hardware/hardware,hardware/fine41,paper/paper")
    parser.add_argument("--seed", type=int, default=61)
    parser.add_argument("--trial", type=int, default=0)
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--out", type=Path, default=Path("docs/figures/hold.png"))
    args = parser.parse_args()
    runs = [r.split("/") for r in args.runs.split(",")]
    fig, axes = plt.subplots(len(runs), 1, figsize=(9, 2.6 * len(runs)), sharex=True, squeeze=False)
    for ax, (preset_name, learner) in zip(axes[:, 0], runs, strict=True):
        t_s, err_m, cmd_deg, episode = hold_trace(preset_name, learner, args.seed, args.trial, args.episodes)
        mm = 1000.0 * err_m
        travel = np.abs(np.diff(cmd_deg)).sum() / (t_s[-1] - t_s[0]) * 60.0
        ax.plot(t_s, mm, color="tab:blue", lw=1.0)
        ax.axhline(0.0, color="tab:green", lw=0.8)
        ax.set_ylabel("depth error, mm", color="tab:blue")
        ax.set_title(f"{preset_name}/{learner}, seed {args.seed} trial {args.trial} episode {episode}: RMS about mean "
                     f"{np.std(mm):.2f} mm, offset {np.mean(mm):.2f} mm, command travel {travel:.0f} deg/min",
                     fontsize=9)
        twin = ax.twinx()
        twin.step(t_s, cmd_deg - np.mean(cmd_deg), where="post", color="tab:orange", lw=0.8)
        twin.set_ylabel("command - its mean, deg", color="tab:orange")
    axes[-1, 0].set_xlabel("time in the episode, s")
    fig.tight_layout()
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
