"""Where a shared learner's trial spends its CPU: each part of the study's trial (plant sub-steps, sensor and
observer, recovery phases, action choice, state and reward, model update, hold bookkeeping, row compilation,
value iteration) repeated on scratch copies; the extra CPU per repeat is what that part costs (issue 29 item 6)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit
from numpy.typing import NDArray

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # run from anywhere

from learning import learner_preset  # noqa: E402
from learning.acting import explore_probability, reward_kernel, select_action_kernel  # noqa: E402
from learning.config import kernel_spec  # noqa: E402
from learning.model import N_ACTIONS  # noqa: E402
from learning.planning import plan_rows  # noqa: E402
from learning.shared import allocate_arrays, compile_shared_rows, record_shared  # noqa: E402
from learning.shared_plan import plan_due  # noqa: E402
from learning.spec import KernelSpec  # noqa: E402
from simulator.parameters import kernel_params, preset  # noqa: E402
from simulator.plant.episode import (  # noqa: E402
    E_CMD,
    E_PLANT_END,
    E_STEPS,
    ENV_SIZE,
    episode_cell_kernel,
    episode_reset_kernel,
    episode_state_kernel,
    episode_step_kernel,
    episode_steps,
    measure_kernel,
    new_env_state,
)
from simulator.plant.kernel import MOTOR, Z, jittered_period_s, plant_step  # noqa: E402
from simulator.study.hold import N_ACC, hold_add, hold_reset  # noqa: E402
from simulator.study.kernel import FAST_MATH_FLAGS, compiled_again  # noqa: E402
from simulator.study.runner import trial_streams  # noqa: E402

# The parts, in the order of a learner step; each is repeated on scratch copies when chosen.
PARTS = ("copies", "plant", "sense+observer", "recovery/restart", "action", "state+reward", "model update",
         "hold", "rows", "value iteration")
(P_COPIES, P_PLANT, P_SENSE, P_RESTART, P_ACTION, P_STATE, P_RECORD, P_HOLD, P_ROWS, P_PLAN) = range(len(PARTS))
N_TALLY = 4  # learner steps, planning calls, sweeps, sum of durations in steps


@njit(cache=True, error_model="numpy")
def _trial(learner_stream: NDArray[np.uint64], env_stream: NDArray[np.uint64], target_depth_m: float,
           spec: KernelSpec, lspec: KernelSpec, episodes: int, part: int, extra: int,
           tally: NDArray[np.int64]) -> None:
    """A shared learner's trial as simulator/study/kernel.py runs it; the chosen part done `extra` more times on
    scratch copies (the copies themselves made for every part, so P_COPIES is their cost alone)."""
    n_states = lspec.z_cells * lspec.zdot_cells * lspec.actuator_bins + 1
    model = allocate_arrays(lspec)
    scratch_model = allocate_arrays(lspec)
    values = np.zeros(n_states)
    q = np.zeros((n_states, N_ACTIONS))
    policy = np.zeros(n_states, dtype=np.int8)
    plan_rows(compile_shared_rows(model, lspec), values, q, policy, lspec, learner_stream)
    env = new_env_state(spec)
    scratch_env = np.empty(ENV_SIZE)
    scratch_stream = np.empty(1, dtype=np.uint64)
    acc, scratch_acc = np.zeros(N_ACC), np.zeros(N_ACC)
    hold_from = episode_steps(spec) // 2
    for episode in range(episodes):
        for _ in range(extra):
            scratch_env[:] = env
            scratch_stream[0] = env_stream[0]
            if part == P_RESTART:
                episode_reset_kernel(scratch_env, target_depth_m, spec, lspec, scratch_stream)
        state = episode_reset_kernel(env, target_depth_m, spec, lspec, env_stream)
        p_explore = explore_probability(episode, lspec)
        hold_reset(acc)
        while True:
            for _ in range(extra):
                scratch_stream[0] = learner_stream[0]
                if part == P_ACTION:
                    select_action_kernel(policy, state, p_explore, lspec, scratch_stream)
            action = select_action_kernel(policy, state, p_explore, lspec, learner_stream)
            motor_before = env[MOTOR]
            env_before = env.copy() if extra > 0 else env
            stream_before = env_stream[0]
            next_state, reward, terminated, truncated = episode_step_kernel(env, action, target_depth_m, spec,
                                                                            lspec, env_stream)
            for _ in range(extra):
                # The plant from before the step; the sensor, state and reward from after it.
                scratch_env[:] = env_before if part == P_PLANT else env
                scratch_stream[0] = stream_before if part == P_PLANT else env_stream[0]
                if part == P_PLANT:
                    plant_step(scratch_env[:E_PLANT_END], scratch_env[E_CMD],
                               jittered_period_s(spec.control_period_s, spec, scratch_stream), spec)
                elif part == P_SENSE:
                    measure_kernel(scratch_env, spec.control_period_s, spec, scratch_stream)
                elif part == P_STATE:
                    s = episode_state_kernel(scratch_env, target_depth_m, spec, lspec)
                    tally[3] += int(reward_kernel(scratch_env[Z], target_depth_m, s, lspec) > 1.0)
                elif part == P_RECORD:
                    record_shared(scratch_model, state, action,
                                  episode_cell_kernel(scratch_env, target_depth_m, spec, lspec), lspec)
                elif part == P_HOLD and env[E_STEPS] > hold_from:
                    hold_add(scratch_acc, scratch_env[Z] - target_depth_m, abs(scratch_env[MOTOR] - motor_before),
                             spec.control_period_s)
            if env[E_STEPS] > hold_from:
                hold_add(acc, env[Z] - target_depth_m, abs(env[MOTOR] - motor_before), spec.control_period_s)
            record_shared(model, state, action, episode_cell_kernel(env, target_depth_m, spec, lspec), lspec)
            tally[0] += 1
            state = next_state
            if terminated or truncated:
                break
        tally[3] += int(env[E_STEPS])
        if not plan_due(model, lspec):
            continue
        for _ in range(extra):
            if part == P_ROWS:
                compile_shared_rows(model, lspec)
            elif part == P_PLAN:
                rows = compile_shared_rows(model, lspec)
                scratch_stream[0] = learner_stream[0]
                plan_rows(rows, values.copy(), q.copy(), policy.copy(), lspec, scratch_stream)
            else:
                # Keep every part's copies alike: what P_PLAN copies besides its work.
                values.copy()
                q.copy()
                policy.copy()
        model.since_plan[:] = 0
        tally[2] += plan_rows(compile_shared_rows(model, lspec), values, q, policy, lspec, learner_stream)
        tally[1] += 1


# The study's fast arithmetic (PlantParams.fast_arithmetic, hardware-fast) in this copy of its trial loop too.
_trial_fast = compiled_again(_trial, "_trial_fast", FAST_MATH_FLAGS)


def cpu_ms(pair: str, trials: int, episodes: int, part: int, extra: int) -> tuple[float, NDArray[np.int64]]:
    """CPU ms per trial-episode of trials 0.. of seed 0 with `extra` repeats of the part, and the tallies."""
    preset_name, learner = pair.split("/")
    params, config = preset(preset_name), learner_preset(learner)
    if not config.shared_model:
        raise SystemExit(f"{learner} is not a shared-model learner")
    spec, lspec = kernel_params(params), kernel_spec(config)
    tally = np.zeros(N_TALLY, dtype=np.int64)
    start = time.process_time()
    for t in range(trials):
        learner_stream, env_stream = trial_streams(0, t)
        trial = _trial_fast if params.fast_arithmetic else _trial
        trial(learner_stream, env_stream, params.target_depth_m, spec, lspec, episodes, part, extra, tally)
    return (time.process_time() - start) / (trials * episodes) * 1e3, tally


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--pairs", default="paper/shared,hardware/hardware", help="preset/learner pairs")
    parser.add_argument("--trials", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=400)
    parser.add_argument("--extra", type=int, default=2, help="extra repeats of a part per real one")
    parser.add_argument("--repeats", type=int, default=2, help="each timing the best of this many")
    args = parser.parse_args()
    n = args.trials * args.episodes
    for pair in args.pairs.split(","):
        for part in range(len(PARTS)):
            cpu_ms(pair, 1, 2, part, 1)  # compile or load outside the timing
        trial_ms, tally = min(cpu_ms(pair, args.trials, args.episodes, P_COPIES, 0) for _ in range(args.repeats))
        copies_ms = min(cpu_ms(pair, args.trials, args.episodes, P_COPIES, args.extra)[0]
                        for _ in range(args.repeats))
        steps = tally[0] / n
        print(f"{pair} ({args.trials} x {args.episodes}, one thread): {trial_ms:.3f} ms CPU per trial-episode, "
              f"{steps:.0f} learner steps ({trial_ms / steps * 1e6:.0f} ns each), "
              f"{tally[2] / tally[1]:.1f} sweeps per planning call", flush=True)
        accounted = 0.0
        for part in range(1, len(PARTS)):
            ms = min(cpu_ms(pair, args.trials, args.episodes, part, args.extra)[0] for _ in range(args.repeats))
            cost = max(ms - copies_ms, 0.0) / args.extra
            accounted += cost
            print(f"  {PARTS[part]:<18} {cost:7.3f} ms {cost / trial_ms:5.0%}  ({cost / steps * 1e6:5.0f} ns/step)",
                  flush=True)
        rest = trial_ms - accounted
        print(f"  {'rest (loop, RNG)':<18} {rest:7.3f} ms {rest / trial_ms:5.0%}", flush=True)


if __name__ == "__main__":
    main()
