"""How much of a shared learner's study is planning: CPU per trial-episode of its trials as the study runs them,
and again with every planning call (and separately every row build) repeated on a copy; the difference is what
planning costs. Bounds what faster planning alone can give a study (issue 29 item 6)."""

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
from learning.acting import explore_probability, select_action_kernel  # noqa: E402
from learning.config import kernel_spec  # noqa: E402
from learning.model import N_ACTIONS  # noqa: E402
from learning.shared import allocate_arrays, compile_shared_rows, record_shared  # noqa: E402
from learning.shared_plan import plan_shared_kernel  # noqa: E402
from learning.spec import KernelSpec  # noqa: E402
from simulator.parameters import kernel_params, preset  # noqa: E402
from simulator.plant.episode import (  # noqa: E402
    episode_cell_kernel,
    episode_reset_kernel,
    episode_step_kernel,
    new_env_state,
)
from simulator.study.runner import trial_streams  # noqa: E402


@njit(cache=True, error_model="numpy")
def _trial(learner_stream: NDArray[np.uint64], env_stream: NDArray[np.uint64], target_depth_m: float,
           spec: KernelSpec, lspec: KernelSpec, episodes: int, extra_plans: int, extra_rows: int) -> int:
    """A shared learner's trial as simulator/study/kernel.py runs it (no hold bookkeeping), each planning call
    done extra_plans more times from the same start on copies and its rows built extra_rows more times;
    returns the sweeps of the real calls (the same whatever the extras)."""
    n_states = lspec.z_cells * lspec.zdot_cells * lspec.actuator_bins + 1
    model = allocate_arrays(lspec)
    values = np.zeros(n_states)
    q = np.zeros((n_states, N_ACTIONS))
    policy = np.zeros(n_states, dtype=np.int8)
    plan_shared_kernel(model, values, q, policy, lspec, learner_stream)
    env = new_env_state(spec)
    sweeps = 0
    for episode in range(episodes):
        state = episode_reset_kernel(env, target_depth_m, spec, lspec, env_stream)
        p_explore = explore_probability(episode, lspec)
        while True:
            action = select_action_kernel(policy, state, p_explore, lspec, learner_stream)
            next_state, _, terminated, truncated = episode_step_kernel(env, action, target_depth_m, spec, lspec,
                                                                        env_stream)
            record_shared(model, state, action, episode_cell_kernel(env, target_depth_m, spec, lspec), lspec)
            state = next_state
            if terminated or truncated:
                break
        start_values, start_stream = values.copy(), learner_stream.copy()
        sweeps += plan_shared_kernel(model, values, q, policy, lspec, learner_stream)
        for _ in range(extra_plans):
            plan_shared_kernel(model, start_values.copy(), q.copy(), policy.copy(), lspec, start_stream.copy())
        for _ in range(extra_rows):
            compile_shared_rows(model, lspec)
    return sweeps


def cpu_ms(pair: str, trials: int, episodes: int, extra_plans: int, extra_rows: int) -> tuple[float, int]:
    """CPU ms per trial-episode of trials 0.. of seed 0 with the extras, and the real calls' sweeps."""
    preset_name, learner = pair.split("/")
    params, config = preset(preset_name), learner_preset(learner)
    if not config.shared_model:
        raise SystemExit(f"{learner} is not a shared-model learner")
    spec, lspec = kernel_params(params), kernel_spec(config)
    start, sweeps = time.process_time(), 0
    for t in range(trials):
        learner_stream, env_stream = trial_streams(0, t)
        sweeps += _trial(learner_stream, env_stream, params.target_depth_m, spec, lspec, episodes, extra_plans,
                         extra_rows)
    return (time.process_time() - start) / (trials * episodes) * 1e3, sweeps


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--pairs", default="paper/shared,hardware/hardware", help="preset/learner pairs")
    parser.add_argument("--trials", type=int, default=3)
    parser.add_argument("--episodes", type=int, default=400)
    parser.add_argument("--extra", type=int, default=2, help="extra planning calls per real one")
    args = parser.parse_args()
    for pair in args.pairs.split(","):
        cpu_ms(pair, 1, 2, 1, 1)  # compile or load outside the timing
        trial_ms, sweeps = cpu_ms(pair, args.trials, args.episodes, 0, 0)
        plan_ms = (cpu_ms(pair, args.trials, args.episodes, args.extra, 0)[0] - trial_ms) / args.extra
        rows_ms = (cpu_ms(pair, args.trials, args.episodes, 0, args.extra)[0] - trial_ms) / args.extra
        print(f"{pair} ({args.trials} x {args.episodes}, one thread): {trial_ms:.3f} ms CPU per trial-episode, "
              f"planning {plan_ms:.3f} ms ({plan_ms / trial_ms:.0%}; rows {rows_ms:.3f} ms, "
              f"{sweeps / (args.trials * args.episodes):.1f} sweeps per call); planning at no cost at all would "
              f"make this study {trial_ms / (trial_ms - plan_ms):.2f}x faster", flush=True)


if __name__ == "__main__":
    main()
