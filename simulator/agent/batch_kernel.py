"""Compiled batches of the on-board program's control steps: many steps, their SAMPLEs framed, logged and queued.

At --speed max the program's per-step Python (mode dispatch, packing, framing, the log append) cost more
than the physics. These kernels run whole steps of the modes that dominate agent time, exactly as
onboard.py runs them, one after another, until something needs the Python program: an event of the
mode (the recovery controller settled or gave up, an episode ended), a dive limit, a HEARTBEAT due, the
batch's step or agent-time budget. Each SAMPLE is packed in messages.Sample's layout, framed (header,
CRC-16/CCITT-FALSE, COBS, delimiter), appended to the on-board log (log_ring.py) and written to one
wire buffer: the same bytes, frame for frame, as the Python path (tests/simulator/agent/test_batch.py).

Where a step stops early (an event or a limit) it stops after its SAMPLE, where the Python step
would act on it; the Python program finishes that step (onboard_batch.py).
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numpy.typing import NDArray

from learning.acting import reward_kernel, select_action_kernel, state_index_kernel
from learning.model import ModelArrays, record_transition
from learning.shared import raw_cell_kernel, record_shared
from learning.spec import KernelSpec
from protocol.enums import PROTOCOL_VERSION
from protocol.fast_frames import cobs_encode_into, crc_into
from simulator.agent.kernel import recovery_period_kernel, sense_kernel
from simulator.agent.log_ring import ring_commit, ring_reserve
from simulator.plant.kernel import MOTOR, plant_step

SAMPLE_ID = 0x20  # messages.Sample.MSG_ID (a test checks they agree)
SAMPLE_PAYLOAD = 48  # messages.Sample's packed size
SAMPLE_INNER = 5 + SAMPLE_PAYLOAD + 2
SAMPLE_WIRE = SAMPLE_INNER + 2  # COBS adds one code byte to a frame this short, then the delimiter
ACTION_NONE = 255
MODE_RECOVERING = 2

# Integer registers of a batch (one int64 array in and out).
T_US, NEXT_SAMPLE, SEQ, EPISODE, STEPS, MODE, WIRE_END, STATUS = 0, 1, 2, 3, 4, 5, 6, 7
HEARTBEAT_DUE_US, UNTIL_US, DIVE_START_US, DT_US, MAX_STEPS, STEPS_RUN, LINK_CHECK = 8, 9, 10, 11, 12, 13, 14
# LEARNING only: the learner's previous (state, action), evictions counted, transitions observed, episode bounds.
PREV_STATE, PREV_ACTION, EVICTIONS, OBSERVED, TERMINAL, STEP_LIMIT, LAST_STATE = 15, 16, 17, 18, 19, 20, 21
N_INTS = 22
# Float registers (one float64 array in and out).
CMD_DEG, CHARGE, HOLD_M, PRESSURE_PA, DEPTH_M, VELOCITY_MPS, LOW_BATTERY_V, MAX_DIVE_S = 0, 1, 2, 3, 4, 5, 6, 7
ENDURANCE_S, DT_S, LINK_TIMEOUT_S, LAST_RX_S = 8, 9, 10, 11
# LEARNING only: the episode's return, exploration, actuator window and target.
RETURN, P_EXPLORE, CENTER_DEG, WINDOW_DEG, ACTION_STEP_DEG, TARGET_M = 12, 13, 14, 15, 16, 17
N_FLOATS = 18
# LINK_CHECK: how the batch sees link loss (SPEC s. 4) when it surfaces the agent.
LINK_IGNORED, LINK_AGENT_CLOCK, LINK_LOST = 0, 1, 2
# Why a batch returned (STATUS).
DONE = 0  # the step budget, the agent-time budget or a HEARTBEAT due: the last step is complete
SETTLED = 1  # RECOVERING: the recovery controller settled (the step stopped after its SAMPLE)
GAVE_UP = 2  # RECOVERING: the recovery controller gave up (the step stopped after its SAMPLE)
LIMIT = 3  # a dive limit holds (the step stopped after its SAMPLE and mode events, before the limit check)
EPISODE_OVER = 4  # LEARNING: the episode's last SAMPLE is out (the learner is not asked to act)


@njit(cache=True, error_model="numpy", inline="always")
def _put(buffer: NDArray[np.uint8], at: int, value: int, size: int) -> None:
    for k in range(size):
        buffer[at + k] = (value >> (8 * k)) & 0xFF


@njit(cache=True, error_model="numpy", inline="always")
def _put_f32(buffer: NDArray[np.uint8], at: int, value: float, f32: NDArray[np.float32],
             f32_bytes: NDArray[np.uint8]) -> None:
    f32[0] = value  # rounded to float32 as struct's "f" rounds it
    for k in range(4):
        buffer[at + k] = f32_bytes[k]


@njit(cache=True, error_model="numpy", inline="always")
def emit_sample(
    ints: NDArray[np.int64], ring_data: NDArray[np.uint8], ring_index: NDArray[np.int64],
    ring_counters: NDArray[np.int64], wire: NDArray[np.uint8], f32: NDArray[np.float32],
    f32_bytes: NDArray[np.uint8], pressure_pa: float, depth_m: float, velocity_mps: float, actuator_deg: float,
    cmd_deg: float, reward: float, state: int, action: int,
) -> None:
    """One SAMPLE (ModeMachine._sample): next sample index and seq, into the log and onto the wire."""
    index = ints[NEXT_SAMPLE]
    ints[NEXT_SAMPLE] = index + 1
    seq = ints[SEQ]
    ints[SEQ] = (seq + 1) & 0xFFFF
    at = ring_reserve(ring_data, ring_index, ring_counters, SAMPLE_INNER)
    inner = ring_data[at:at + SAMPLE_INNER]
    inner[0] = PROTOCOL_VERSION
    inner[1] = 0
    inner[2] = seq & 0xFF
    inner[3] = seq >> 8
    inner[4] = SAMPLE_ID
    _put(inner, 5, ints[T_US], 8)
    _put(inner, 13, index, 4)
    _put(inner, 17, ints[EPISODE], 4)
    _put(inner, 21, ints[STEPS], 4)
    _put_f32(inner, 25, pressure_pa, f32, f32_bytes)
    _put_f32(inner, 29, depth_m, f32, f32_bytes)
    _put_f32(inner, 33, velocity_mps, f32, f32_bytes)
    _put_f32(inner, 37, actuator_deg, f32, f32_bytes)
    _put_f32(inner, 41, cmd_deg, f32, f32_bytes)
    _put_f32(inner, 45, reward, f32, f32_bytes)
    _put(inner, 49, state, 2)
    inner[51] = action
    inner[52] = ints[MODE]
    crc_into(inner, SAMPLE_INNER - 2)
    ring_commit(ring_index, ring_counters, index, SAMPLE_INNER, True)
    ints[WIRE_END] = cobs_encode_into(inner, SAMPLE_INNER, wire, ints[WIRE_END])


@njit(cache=True, error_model="numpy", inline="always")
def battery_voltage(charge: float, socs: NDArray[np.float64], volts: NDArray[np.float64]) -> float:
    """Battery.voltage_v: the discharge curve interpolated at the state of charge."""
    n = socs.shape[0]
    upper = 1
    while upper < n and socs[upper] < charge:  # bisect_left(socs, charge, 1)
        upper += 1
    if upper == n:
        return volts[n - 1]
    soc0, v0, soc1, v1 = socs[upper - 1], volts[upper - 1], socs[upper], volts[upper]
    return v0 + (v1 - v0) * (charge - soc0) / (soc1 - soc0)


@njit(cache=True, error_model="numpy", inline="always")
def limit_holds(ints: NDArray[np.int64], floats: NDArray[np.float64], socs: NDArray[np.float64],
                volts: NDArray[np.float64]) -> bool:
    """ModeMachine._check_limits would surface the agent now (battery, dive time, link loss)."""
    if battery_voltage(floats[CHARGE], socs, volts) < floats[LOW_BATTERY_V]:
        return True
    max_dive_s = floats[MAX_DIVE_S]
    if max_dive_s != 0.0 and ints[T_US] - ints[DIVE_START_US] >= max_dive_s * 1e6:
        return True
    check = ints[LINK_CHECK]
    if check == LINK_LOST:
        return True
    return check == LINK_AGENT_CLOCK and ints[T_US] / 1e6 - floats[LAST_RX_S] >= floats[LINK_TIMEOUT_S]


@njit(cache=True, error_model="numpy", inline="always")
def advance(ints: NDArray[np.int64], floats: NDArray[np.float64], plant: NDArray[np.float64],
            spec: KernelSpec) -> None:
    """SimulatedHardware.advance: the plant moves under the held command, the battery drains, the clock ticks."""
    dt_s = floats[DT_S]
    plant_step(plant, floats[CMD_DEG], dt_s, spec)
    floats[CHARGE] = max(0.0, floats[CHARGE] - dt_s / floats[ENDURANCE_S])
    ints[T_US] += ints[DT_US]


@njit(cache=True, error_model="numpy", inline="always")
def step_ends_batch(ints: NDArray[np.int64], floats: NDArray[np.float64], plant: NDArray[np.float64],
                    spec: KernelSpec, socs: NDArray[np.float64], volts: NDArray[np.float64]) -> bool:
    """The end of a step after its SAMPLE: a dive limit (STATUS LIMIT), else the hardware advances; True if
    the batch must return then (the limit, or a HEARTBEAT due)."""
    if limit_holds(ints, floats, socs, volts):
        ints[STATUS] = LIMIT
        return True
    advance(ints, floats, plant, spec)
    return ints[T_US] >= ints[HEARTBEAT_DUE_US]


@njit(cache=True, error_model="numpy")
def held_steps(
    ints: NDArray[np.int64], floats: NDArray[np.float64], plant: NDArray[np.float64],
    observer: NDArray[np.float64], recovery: NDArray[np.float64], sensor_rng: NDArray[np.uint64],
    use_observer: bool, spec: KernelSpec, socs: NDArray[np.float64], volts: NDArray[np.float64],
    ring_data: NDArray[np.uint8], ring_index: NDArray[np.int64], ring_counters: NDArray[np.int64],
    wire: NDArray[np.uint8],
) -> None:
    """Steps of RECOVERING, HOVER or PAUSED (ModeMachine._controller_step) until the batch must return."""
    f32 = np.empty(1, np.float32)
    f32_bytes = f32.view(np.uint8)
    alpha_max = spec.alpha_max_deg
    recovering = ints[MODE] == MODE_RECOVERING
    ints[STATUS] = DONE
    ints[STEPS_RUN] = 0
    while ints[STEPS_RUN] < ints[MAX_STEPS] and ints[T_US] < ints[UNTIL_US]:
        pressure, depth, velocity, cmd, settled, gave_up = recovery_period_kernel(
            plant, observer, recovery, sensor_rng, use_observer, floats[HOLD_M], floats[DT_S], spec
        )
        cmd = min(max(cmd, 0.0), alpha_max)
        floats[CMD_DEG] = cmd
        floats[PRESSURE_PA], floats[DEPTH_M], floats[VELOCITY_MPS] = pressure, depth, velocity
        emit_sample(ints, ring_data, ring_index, ring_counters, wire, f32, f32_bytes, pressure, depth, velocity,
                    plant[MOTOR], cmd, 0.0, 0, ACTION_NONE)
        ints[STEPS_RUN] += 1
        if recovering and (settled or gave_up):
            ints[STATUS] = SETTLED if settled else GAVE_UP
            return
        if step_ends_batch(ints, floats, plant, spec, socs, volts):
            return


@njit(cache=True, error_model="numpy")
def learning_steps(
    ints: NDArray[np.int64], floats: NDArray[np.float64], plant: NDArray[np.float64],
    observer: NDArray[np.float64], sensor_rng: NDArray[np.uint64], use_observer: bool, spec: KernelSpec,
    socs: NDArray[np.float64], volts: NDArray[np.float64], ring_data: NDArray[np.uint8],
    ring_index: NDArray[np.int64], ring_counters: NDArray[np.int64], wire: NDArray[np.uint8],
    lspec: KernelSpec, policy: NDArray[np.int8], learner_rng: NDArray[np.uint64], model: ModelArrays,
) -> None:
    """Steps of LEARNING (ModeMachine._learning_step with Learner.observe and act) until the batch must return.

    The learner's velocity is the sensed one (a k-step depth difference runs step by step in Python).
    """
    f32 = np.empty(1, np.float32)
    f32_bytes = f32.view(np.uint8)
    alpha_max = spec.alpha_max_deg
    shared = lspec.shared_model
    local = (not shared) or lspec.dirichlet_weight != 0.0
    sparse = lspec.model_form == 1
    target, center, window = floats[TARGET_M], floats[CENTER_DEG], floats[WINDOW_DEG]
    ints[STATUS] = DONE
    ints[STEPS_RUN] = 0
    while ints[STEPS_RUN] < ints[MAX_STEPS] and ints[T_US] < ints[UNTIL_US]:
        pressure, depth, velocity = sense_kernel(plant, observer, sensor_rng, use_observer, floats[DT_S], spec)
        floats[PRESSURE_PA], floats[DEPTH_M], floats[VELOCITY_MPS] = pressure, depth, velocity
        cmd = floats[CMD_DEG]
        fraction = (cmd - center) / window
        state = state_index_kernel(depth, velocity, target, fraction, lspec)
        reward = 0.0
        prev_state, prev_action = ints[PREV_STATE], ints[PREV_ACTION]
        if prev_state >= 0:
            reward = reward_kernel(depth, target, state, lspec)
            floats[RETURN] += reward
            if shared:
                cell = raw_cell_kernel(depth, velocity, target, fraction, lspec)
                if record_shared(model, prev_state, prev_action, cell, lspec):
                    ints[EVICTIONS] += 1
            if local and record_transition(model.succ_idx, model.succ_cnt, model.reward_sum, prev_state, prev_action,
                                           reward, state, sparse):
                ints[EVICTIONS] += 1
            ints[OBSERVED] += 1
        ints[STEPS_RUN] += 1
        if state == ints[TERMINAL] or ints[STEPS] >= ints[STEP_LIMIT]:
            emit_sample(ints, ring_data, ring_index, ring_counters, wire, f32, f32_bytes, pressure, depth, velocity,
                        plant[MOTOR], cmd, reward, state, ACTION_NONE)
            ints[LAST_STATE] = state  # for the Python program to end the episode with
            ints[STATUS] = EPISODE_OVER
            return
        action = select_action_kernel(policy, state, floats[P_EXPLORE], lspec, learner_rng)
        step = floats[ACTION_STEP_DEG] if action == 1 else -floats[ACTION_STEP_DEG]
        cmd = min(max(cmd + step, center - window), center + window)
        cmd = min(max(cmd, 0.0), alpha_max)
        floats[CMD_DEG] = cmd
        ints[PREV_STATE], ints[PREV_ACTION] = state, action
        emit_sample(ints, ring_data, ring_index, ring_counters, wire, f32, f32_bytes, pressure, depth, velocity,
                    plant[MOTOR], cmd, reward, state, action)
        ints[STEPS] += 1
        if step_ends_batch(ints, floats, plant, spec, socs, volts):
            return
