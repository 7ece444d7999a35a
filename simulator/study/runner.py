"""The batch study: N seeded trials x E episodes of a learner on a preset, both cores, with progress."""

from __future__ import annotations

import os
import threading
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numba
import numpy as np
from numpy.typing import NDArray

from learning import LearnerConfig, model_memory_bytes, n_states
from learning.config import kernel_spec
from learning.rng import new_stream
from simulator.errors import StudyError
from simulator.parameters import PlantParams, kernel_params
from simulator.study.kernel import TrialArrays, trial_kernels

_POLL_S = 0.1


@dataclass(frozen=True)
class StudyResult:
    """Everything a study produced, one row per trial."""

    durations_s: NDArray[np.float64]  # [trials, episodes] time in the region per episode
    values: NDArray[np.float64]  # [trials, states] value function after the last episode
    policy: NDArray[np.int8]  # [trials, states] greedy policy after the last episode
    wall_s: float  # wall time of the compiled run (compilation excluded when cached)
    memory_bytes: int  # the learner's model size on the Teensy
    threads: int  # threads the trials ran on
    seed: int
    # [trials, 4]: model slot evictions, planning sweeps in all, most sweeps of one call, planning calls
    counters: NDArray[np.int64] | None = None
    seeds: tuple[int, ...] = ()  # every seed pooled, trials of seeds[0] first
    hold: NDArray[np.float64] | None = None  # [trials, episodes, N_HOLD] hold quality per successful episode
    # [trials, RECOVERY_HOLDS, N_HOLD] the recovery controller's, after each trial's last episode on its plant
    recovery_hold: NDArray[np.float64] | None = None


def trial_streams(seed: int, trial: int) -> tuple[NDArray[np.uint64], NDArray[np.uint64]]:
    """The learner's and the environment's random streams of one trial (what a Python loop reuses)."""
    learner_rng = np.random.default_rng([seed, trial, 0])
    env_rng = np.random.default_rng([seed, trial, 1])
    return new_stream(learner_rng), new_stream(env_rng)


def run_study(
    params: PlantParams,
    config: LearnerConfig,
    trials: int,
    episodes: int,
    seed: int = 0,
    on_progress: Callable[[int], None] | None = None,
    threads: int | None = None,
    seeds: Sequence[int] | None = None,
    plants: Sequence[PlantParams] | None = None,
) -> StudyResult:
    """Run the trials in parallel; on_progress(episodes done over all trials) is called as they go.

    With seeds, `trials` trials of each seed are pooled (trial t of seed k is the same trial as in a
    study of that seed alone). With plants (one per pooled trial, a plant family's draws), each trial
    runs on its own plant; a trial on `params` gives the same result either way.
    """
    if trials <= 0 or episodes <= 0:
        raise StudyError(f"trials and episodes must be positive (got {trials} and {episodes})")
    seed_list = tuple(seeds) if seeds else (seed,)
    seed = seed_list[0]
    numba_threads: int = numba.config.NUMBA_NUM_THREADS  # type: ignore[attr-defined]
    streams = [trial_streams(k, t) for k in seed_list for t in range(trials)]
    trials = len(streams)
    threads = max(1, min(threads or os.cpu_count() or 1, numba_threads, trials))
    learner_streams = np.array([s[0] for s in streams])
    env_streams = np.array([s[1] for s in streams])
    progress = np.zeros(trials, dtype=np.int64)
    if plants is not None and len(plants) != trials:
        raise StudyError(f"{len(plants)} plants for {trials} trials")
    out = TrialArrays.zeros((trials,), episodes, n_states(config))
    durations, values, policy, counters, hold, recovery_hold = out
    lspec = kernel_spec(config)
    args = (learner_streams, env_streams, params.target_depth_m, kernel_params(params), lspec, out, progress)
    failure: list[BaseException] = []

    def one_trial(t: int) -> None:
        assert plants is not None
        spec = kernel_params(plants[t])
        trial_kernels(plants[t]).run_trial(learner_streams[t], env_streams[t], plants[t].target_depth_m, spec, lspec,
                                           out.row(t), progress, t)

    def work() -> None:
        try:
            if plants is None:
                numba.set_num_threads(threads)
                # Trials differ in length: hand them out one at a time so neither core idles at the end.
                with numba.parallel_chunksize(1):
                    trial_kernels(params).run_trials(*args)
            else:
                # One plant per trial: numba's prange takes one spec, so trials go to threads here (the
                # trial kernel releases the GIL), one at a time as in the batch.
                with ThreadPoolExecutor(threads) as pool:
                    list(pool.map(one_trial, range(trials)))
        except BaseException as e:  # re-raised in the caller's thread below
            failure.append(e)

    start = time.perf_counter()
    worker = threading.Thread(target=work, name="study-trials", daemon=True)
    worker.start()
    while worker.is_alive():
        worker.join(_POLL_S)
        if on_progress is not None:
            on_progress(int(progress.sum()))
    wall_s = time.perf_counter() - start
    if failure:
        raise StudyError(f"study failed: {failure[0]}") from failure[0]
    return StudyResult(durations, values, policy, wall_s, model_memory_bytes(config), threads, seed, counters,
                       seed_list, hold, recovery_hold)
