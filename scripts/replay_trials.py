"""Why a study trial is never stable: replays trials with the study's kernels and says how late episodes end.

    .venv/bin/python scripts/replay_trials.py [--params docs/perturbations/noise2.toml] [--seed 10]
        [--trials 20] [--learner hardware] [--z-tol 0.1 --zdot-tol 0.04] [--last 100]

Replays each trial with simulator/study/kernel.py's replay_trial (run_trial's loop and streams: the durations are
the study's), which records every step, and says per episode what ended it: the depth edge or the velocity edge
of the learning region (as the learner measured it), and the true velocity, the learner's velocity error and the
actuator window's offset from the true neutral at that moment. Not a test (issue 29).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from numpy.typing import NDArray
from rich.console import Console
from rich.table import Table

from learning import LearnerConfig, n_states
from learning.config import kernel_spec
from learning.presets import learner_preset
from simulator.parameters import PlantParams, kernel_params, load_params, preset
from simulator.plant.episode import E_CENTER, E_CMD, E_DEPTH_MEAS, E_VEL_EST, E_ZDOT, neutral_alpha_kernel
from simulator.study.kernel import S_ACTION, S_ENV, S_STATE, StepRecord, TrialArrays, trial_kernels
from simulator.study.runner import trial_streams
from simulator.study.stats import per_trial

# The env entries recorded at every step, and their columns in a recorded step.
COLUMNS = np.array([E_DEPTH_MEAS, E_VEL_EST, E_ZDOT, E_CMD, E_CENTER], dtype=np.int64)
S_DEPTH, S_VEL, S_TRUE_VEL, S_CMD, S_CENTER = range(S_ENV, S_ENV + len(COLUMNS))
# Columns of an episode's record.
R_STEPS, R_END, R_ERR, R_VEL, R_TRUE_VEL, R_VEL_RMS, R_CENTER_OFF, R_FRACTION, R_SWITCHES = range(9)
N_REC = 9
END_HELD, END_DEPTH, END_VELOCITY = 0, 1, 2


def episode_records(
    steps: list[NDArray[np.float64]], params: PlantParams, config: LearnerConfig, neutral_deg: float
) -> NDArray[np.float64]:
    """One row of R_* columns per episode from its recorded steps: what ended it, and the state at its end."""
    records = np.zeros((len(steps), N_REC))
    terminal = n_states(config) - 1
    for row, episode in zip(records, steps, strict=True):
        last = episode[-1]
        err = last[S_DEPTH] - params.target_depth_m
        if last[S_STATE] != terminal:  # an episode not ended by the terminal state lasted its full time
            row[R_END] = END_HELD
        elif abs(err) >= config.z_tol_m:
            row[R_END] = END_DEPTH
        else:
            row[R_END] = END_VELOCITY
        actions = episode[:, S_ACTION]
        row[R_STEPS] = len(episode)
        row[R_ERR] = err
        row[R_VEL] = last[S_VEL]
        row[R_TRUE_VEL] = last[S_TRUE_VEL]
        row[R_VEL_RMS] = np.sqrt(np.mean((episode[:, S_VEL] - episode[:, S_TRUE_VEL]) ** 2))
        row[R_CENTER_OFF] = last[S_CENTER] - neutral_deg
        row[R_FRACTION] = (last[S_CMD] - last[S_CENTER]) / params.action_window_deg
        row[R_SWITCHES] = np.count_nonzero(actions[1:] != actions[:-1]) / len(episode)
    return records


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", type=Path, default=None)
    ap.add_argument("--seed", type=int, default=10)
    ap.add_argument("--trials", type=int, default=20)
    ap.add_argument("--episodes", type=int, default=400)
    ap.add_argument("--learner", default="hardware")
    ap.add_argument("--z-tol", type=float, default=0.1)
    ap.add_argument("--zdot-tol", type=float, default=0.04)
    ap.add_argument("--last", type=int, default=100, help="late episodes: the last this many")
    ap.add_argument("--set", action="append", default=[], help="a learner field, e.g. filter_depth_gain=0.5")
    ap.add_argument("--trace", type=int, default=-1, help="print this trial's last failed episode, step by step")
    args = ap.parse_args()
    params = preset("hardware")
    if args.params is not None:
        params = load_params(args.params, params)
    overrides = {k.strip(): float(v) for k, _, v in (text.partition("=") for text in args.set)}
    config = replace(learner_preset(args.learner, **overrides), z_tol_m=args.z_tol, zdot_tol_mps=args.zdot_tol)
    spec, lspec = kernel_params(params), kernel_spec(config)
    neutral_deg = float(neutral_alpha_kernel(spec))
    records = np.zeros((args.trials, args.episodes, N_REC))
    durations = np.zeros((args.trials, args.episodes))
    limit = round(params.episode_limit_s / params.control_period_s)
    record = StepRecord(COLUMNS, np.zeros((args.episodes, limit, S_ENV + len(COLUMNS))))
    for t in range(args.trials):
        ls, es = trial_streams(args.seed, t)
        out = TrialArrays.zeros((), args.episodes, n_states(config))
        trial_kernels(params).replay_trial(ls, es, params.target_depth_m, spec, lspec, out, record)
        durations[t] = out.durations_s
        steps = [record.rows[e, :round(d / params.control_period_s)] for e, d in enumerate(out.durations_s)]
        records[t] = episode_records(steps, params, config, neutral_deg)
        failed = np.nonzero(records[t, :, R_END] != END_HELD)[0]
        if t == args.trace and len(failed):
            for k, step in enumerate(steps[failed[-1]]):
                err = step[S_DEPTH] - params.target_depth_m
                fraction = (step[S_CMD] - step[S_CENTER]) / params.action_window_deg
                print(f"{k * params.control_period_s:6.1f} s  err {err * 1000:+6.1f} mm  v {step[S_VEL] * 1000:+5.1f}  "
                      f"true {step[S_TRUE_VEL] * 1000:+5.1f} mm/s  bin frac {fraction:+.2f}  "
                      f"action {int(step[S_ACTION])}")
    rows = per_trial(durations, params.episode_limit_s)
    table = Table(title=f"late episodes (last {args.last}), seed {args.seed}, {args.z_tol}/{args.zdot_tol}")
    for col in ("trial", "stable from", "fails", "depth edge", "vel edge", "fail at s", "|true v| at vel end",
                "v est. RMS err", "window off deg", "bin frac at end", "switch/step"):
        table.add_column(col)
    for t, row in enumerate(rows):
        late = records[t, -args.last:]
        fail = late[late[:, R_END] != END_HELD]
        vel_end = fail[fail[:, R_END] == END_VELOCITY]
        table.add_row(
            str(t), str(row["alc_stable_from"]), str(len(fail)),
            str(int(np.sum(fail[:, R_END] == END_DEPTH))), str(len(vel_end)),
            " ".join(f"{x * params.control_period_s:.0f}" for x in fail[:6, R_STEPS]),
            f"{np.mean(np.abs(vel_end[:, R_TRUE_VEL])):.3f}" if len(vel_end) else "-",
            f"{np.mean(late[:, R_VEL_RMS]) * 1000:.1f} mm/s",
            f"{np.mean(late[:, R_CENTER_OFF]):+.2f}",
            f"{np.mean(fail[:, R_FRACTION]):+.2f}" if len(fail) else "-",
            f"{np.mean(late[:, R_SWITCHES]):.2f}",
        )
    console = Console()
    console.print(table)
    never = [t for t, row in enumerate(rows) if row["alc_stable_from"] is None]
    late = records[never, -args.last:].reshape(-1, N_REC)
    fail = late[late[:, R_END] != END_HELD]
    console.print(
        f"never stable: {len(never)} of {args.trials}; their late failures: {len(fail)} "
        f"({int(np.sum(fail[:, R_END] == END_VELOCITY))} at the velocity edge), after a median "
        f"{np.median(fail[:, R_STEPS]) * params.control_period_s if len(fail) else float('nan'):.0f} s of the episode; "
        f"velocity error of the learner's input, RMS over all late episodes: "
        f"{np.mean(records[:, -args.last:, R_VEL_RMS]) * 1000:.1f} mm/s", soft_wrap=True)


if __name__ == "__main__":
    main()
