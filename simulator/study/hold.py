"""Hold quality: how well a successful episode holds the target, and the same for the agent's recovery controller
holding the target on the same plant, at the same plant time and in the same plant state.

Both are measured on the true depth over the second half of the episode (150-300 s at the default limit):
the hold once the approach from the random start is over. The error splits into its offset (the mean true-depth
error, which a sensor bias or drift sets and no controller that trusts its sensor can remove) and the oscillation
about that mean (RMS and peak-to-peak): what a policy's chatter adds. Actuator travel is the stepper's path
length (the battery's cost), per minute of hold.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit, prange
from numpy.typing import NDArray

from learning.spec import KernelSpec
from simulator.plant.episode import (
    E_CMD,
    E_DEPTH_MEAS,
    E_MOTOR,
    E_OBS_X2,
    E_PLANT_END,
    E_REC_AVG,
    E_REC_ELAPSED,
    episode_reset_kernel,
    episode_steps,
    measure_kernel,
    new_env_state,
)
from simulator.plant.kernel import MOTOR, Z, plant_step
from simulator.plant.recovery import recovery_init, recovery_update_kernel

# Columns of a hold row: RMS of the error, its peak-to-peak, travel; then the offset (mean error) and the RMS about it
# (the first three as before issue 43, so earlier studies' rows keep their meaning).
H_RMS_M, H_P2P_M, H_TRAVEL_DPM, H_OFFSET_M, H_OSC_RMS_M = 0, 1, 2, 3, 4
N_HOLD = 5
_SUM_SQ, _N, _MIN, _MAX, _TRAVEL, _TIME, _SUM = 0, 1, 2, 3, 4, 5, 6  # accumulator layout
N_ACC = 7
RECOVERY_HOLDS = 3  # recovery-controller holds per trial (each one episode long)


@njit(cache=True, error_model="numpy", inline="always")
def hold_reset(acc: NDArray[np.float64]) -> None:
    acc[:] = 0.0
    acc[_MIN] = np.inf
    acc[_MAX] = -np.inf


@njit(cache=True, error_model="numpy", inline="always")
def hold_add(acc: NDArray[np.float64], error_m: float, travel_deg: float, dt_s: float) -> None:
    """One control period of the hold: the depth error at its end and the stepper's travel during it."""
    acc[_SUM_SQ] += error_m * error_m
    acc[_SUM] += error_m
    acc[_N] += 1.0
    acc[_MIN] = min(acc[_MIN], error_m)
    acc[_MAX] = max(acc[_MAX], error_m)
    acc[_TRAVEL] += travel_deg
    acc[_TIME] += dt_s


@njit(cache=True, error_model="numpy", inline="always")
def hold_write(acc: NDArray[np.float64], row: NDArray[np.float64], success: bool) -> None:
    """The hold row of an episode: NaN unless it succeeded."""
    if not success or acc[_N] == 0.0:
        row[:] = np.nan
        return
    mean_sq = acc[_SUM_SQ] / acc[_N]
    offset = acc[_SUM] / acc[_N]
    row[H_RMS_M] = np.sqrt(mean_sq)
    row[H_P2P_M] = acc[_MAX] - acc[_MIN]
    row[H_TRAVEL_DPM] = acc[_TRAVEL] / acc[_TIME] * 60.0
    row[H_OFFSET_M] = offset
    # E[e^2] - E[e]^2 can round a hair below 0 for a constant error.
    row[H_OSC_RMS_M] = np.sqrt(max(mean_sq - offset * offset, 0.0))


@njit(cache=True, error_model="numpy")
def recovery_hold_run(
    env: NDArray[np.float64], env_stream: NDArray[np.uint64], target_depth_m: float, spec: KernelSpec,
    lspec: KernelSpec, hold: NDArray[np.float64],
) -> None:
    """The recovery controller holding target_depth_m for an episode's length, len(hold) times, on the trial's own
    environment where its episodes left it: the same plant time (a drifting sensor has drifted as far), the same
    sensor state and the neutral angle the controller has learned, each hold from the start an episode would have.

    Called after a trial's last episode, so the trial's own figures do not depend on it."""
    acc = np.zeros(N_ACC)
    dt = spec.recovery_period_s
    n_steps = int(np.round(episode_steps(spec) * spec.control_period_s / dt))
    rec = env[E_REC_AVG:E_REC_ELAPSED + 1]
    plant = env[:E_PLANT_END]
    for h in range(hold.shape[0]):
        episode_reset_kernel(env, target_depth_m, spec, lspec, env_stream)
        recovery_init(rec, rec[0])
        hold_reset(acc)
        for step in range(n_steps):
            measure_kernel(env, dt, spec, env_stream)
            env[E_CMD] = recovery_update_kernel(rec, env[E_DEPTH_MEAS], env[E_OBS_X2], env[E_MOTOR],
                                                target_depth_m, dt, spec)
            motor_before = env[MOTOR]
            plant_step(plant, env[E_CMD], dt, spec)
            if step >= n_steps // 2:
                hold_add(acc, env[Z] - target_depth_m, abs(env[MOTOR] - motor_before), dt)
        hold_write(acc, hold[h], True)


@njit(cache=True, error_model="numpy", nogil=True, parallel=True)
def recovery_holds(
    env_streams: NDArray[np.uint64], target_depth_m: float, spec: KernelSpec, lspec: KernelSpec,
    hold: NDArray[np.float64],
) -> None:
    """The controller alone on a fresh plant per trial (row t of hold from env_streams[t]): what a benchmark of the
    controller wants; a study measures it after its trial instead (recovery_hold_run, simulator/study/kernel.py)."""
    for t in prange(hold.shape[0]):
        recovery_hold_run(new_env_state(spec), env_streams[t], target_depth_m, spec, lspec, hold[t])


def _quartiles(x: NDArray[np.float64], digits: int) -> dict[str, Any]:
    if x.size == 0:
        return {"median": None, "q25": None, "q75": None}
    q25, med, q75 = np.percentile(x, [25, 50, 75])
    return {"median": round(float(med), digits), "q25": round(float(q25), digits), "q75": round(float(q75), digits)}


def _block(rows: NDArray[np.float64]) -> dict[str, Any]:
    ok = rows[~np.isnan(rows[:, H_RMS_M])]
    return {
        "episodes": int(ok.shape[0]),
        "rms_depth_error_mm": _quartiles(1000.0 * ok[:, H_RMS_M], 2),
        "oscillation_rms_mm": _quartiles(1000.0 * ok[:, H_OSC_RMS_M], 2),
        "offset_mm": _quartiles(1000.0 * ok[:, H_OFFSET_M], 2),
        "peak_to_peak_mm": _quartiles(1000.0 * ok[:, H_P2P_M], 1),
        "actuator_travel_deg_per_min": _quartiles(ok[:, H_TRAVEL_DPM], 1),
    }


def hold_summary(learner_hold: NDArray[np.float64], recovery_hold: NDArray[np.float64] | None) -> dict[str, Any]:
    """summary.json's hold_quality: medians [IQR] over the successful episodes, the recovery controller's, ratios.

    learner_hold is [trials, episodes, N_HOLD]; the learner's figures are taken over its last 50 episodes
    (the learned policy, not the exploring one)."""
    learned = learner_hold[:, -50:, :].reshape(-1, N_HOLD)
    out: dict[str, Any] = {
        "window": "true depth over the second half of each successful episode; learner: its last 50 episodes; "
                  "recovery controller: right after them, on the same plant and plant state",
        "learner": _block(learned),
    }
    if recovery_hold is not None:
        out["recovery"] = _block(recovery_hold.reshape(-1, N_HOLD))
        for key, name in (("rms_depth_error_mm", "rms_ratio"), ("oscillation_rms_mm", "oscillation_ratio"),
                          ("actuator_travel_deg_per_min", "travel_ratio"), ("peak_to_peak_mm", "peak_to_peak_ratio")):
            a, b = out["learner"][key]["median"], out["recovery"][key]["median"]
            out[name] = None if a is None or not b else round(a / b, 3)
    return out
