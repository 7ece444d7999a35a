"""Why a study trial is never stable: replays trials with the study's kernels and says how late episodes end.

    .venv/bin/python scripts/replay_trials.py [--params docs/perturbations/noise2.toml] [--seed 10]
        [--trials 20] [--learner hardware] [--z-tol 0.1 --zdot-tol 0.04] [--last 100]

Runs each trial exactly as simulator/study/kernel.py's run_trial does (same streams, same kernels; the
durations match the study's) and records, per episode, what ended it: the depth edge or the velocity
edge of the learning region (as the learner measured it), and the true velocity, the learner's velocity
error and the actuator window's offset from the true neutral at that moment. Not a test (issue 29).
"""

from __future__ import annotations

import argparse
from dataclasses import replace
from pathlib import Path

import numpy as np
from numba import njit
from numpy.typing import NDArray
from rich.console import Console
from rich.table import Table

from learning.acting import select_action_kernel
from learning.config import kernel_spec
from learning.presets import learner_preset
from learning.shared import allocate_arrays, plan_shared_kernel, record_shared
from learning.spec import KernelSpec
from simulator.parameters import kernel_params, load_params, preset
from simulator.plant.episode import (
    E_CENTER,
    E_CMD,
    E_DEPTH_MEAS,
    E_STEPS,
    E_VEL_EST,
    episode_cell_kernel,
    episode_reset_kernel,
    episode_step_kernel,
    neutral_alpha_kernel,
    new_env_state,
)
from simulator.plant.kernel import ZDOT, Z
from simulator.study.runner import trial_streams
from simulator.study.stats import per_trial

# Columns of an episode's record.
R_STEPS, R_END, R_ERR, R_VEL, R_TRUE_VEL, R_VEL_RMS, R_CENTER_OFF, R_FRACTION, R_SWITCHES = range(9)
N_REC = 9
END_HELD, END_DEPTH, END_VELOCITY = 0, 1, 2


@njit(cache=True, error_model="numpy")
def replay_trial(
    learner_stream: NDArray[np.uint64],
    env_stream: NDArray[np.uint64],
    target_depth_m: float,
    spec: KernelSpec,
    lspec: KernelSpec,
    records: NDArray[np.float64],
    trace: NDArray[np.float64],
) -> None:
    """run_trial's loop (shared model, no exploration) with one row of records per episode; trace gets the
    steps (error, learner's velocity, true velocity, actuator fraction, action) of the last failed episode."""
    n_states = lspec.z_cells * lspec.zdot_cells * lspec.actuator_bins + 1
    model = allocate_arrays(lspec)
    values = np.zeros(n_states)
    q = np.zeros((n_states, 2))
    policy = np.zeros(n_states, dtype=np.int8)
    plan_shared_kernel(model, values, q, policy, lspec, learner_stream)
    env = new_env_state(spec)
    neutral = neutral_alpha_kernel(spec)
    steps_now = np.zeros_like(trace)
    for episode in range(records.shape[0]):
        state = episode_reset_kernel(env, target_depth_m, spec, lspec, env_stream)
        sq = 0.0
        switches = 0
        last_action = -1
        while True:
            action = select_action_kernel(policy, state, 0.0, lspec, learner_stream)
            if last_action >= 0 and action != last_action:
                switches += 1
            last_action = action
            next_state, _, terminated, truncated = episode_step_kernel(
                env, action, target_depth_m, spec, lspec, env_stream
            )
            sq += (env[E_VEL_EST] - env[ZDOT]) ** 2
            k = int(env[E_STEPS]) - 1
            if k < steps_now.shape[0]:
                steps_now[k, 0] = env[E_DEPTH_MEAS] - target_depth_m
                steps_now[k, 1] = env[E_VEL_EST]
                steps_now[k, 2] = env[ZDOT]
                steps_now[k, 3] = (env[E_CMD] - env[E_CENTER]) / spec.action_window_deg
                steps_now[k, 4] = action
            cell = episode_cell_kernel(env, target_depth_m, spec, lspec)
            record_shared(model, state, action, cell, lspec)
            state = next_state
            if terminated or truncated:
                break
        row = records[episode]
        steps = env[E_STEPS]
        row[R_STEPS] = steps
        err = env[E_DEPTH_MEAS] - target_depth_m
        if truncated:
            row[R_END] = END_HELD
        elif abs(err) >= lspec.z_tol_m:
            row[R_END] = END_DEPTH
        else:
            row[R_END] = END_VELOCITY
        row[R_ERR] = err
        row[R_VEL] = env[E_VEL_EST]
        row[R_TRUE_VEL] = env[ZDOT]
        row[R_VEL_RMS] = np.sqrt(sq / steps)
        row[R_CENTER_OFF] = env[E_CENTER] - neutral
        row[R_FRACTION] = (env[E_CMD] - env[E_CENTER]) / spec.action_window_deg
        row[R_SWITCHES] = switches / steps
        if terminated:
            trace[:] = np.nan
            trace[:int(steps)] = steps_now[:int(steps)]
        plan_shared_kernel(model, values, q, policy, lspec, learner_stream)
        _ = env[Z]


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
    records = np.zeros((args.trials, args.episodes, N_REC))
    trace = np.full((int(params.episode_limit_s / params.control_period_s) + 1, 5), np.nan)
    for t in range(args.trials):
        ls, es = trial_streams(args.seed, t)
        replay_trial(ls, es, params.target_depth_m, spec, lspec, records[t], trace)
        if t == args.trace:
            for k, (e, v, tv, f, a) in enumerate(trace[~np.isnan(trace[:, 0])]):
                print(f"{k * params.control_period_s:6.1f} s  err {e * 1000:+6.1f} mm  v {v * 1000:+5.1f}  "
                      f"true {tv * 1000:+5.1f} mm/s  bin frac {f:+.2f}  action {int(a)}")
    durations = records[:, :, R_STEPS] * params.control_period_s
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
