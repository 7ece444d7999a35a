"""Runs the on-board program many control steps per call: compiled batches where the mode allows, else step by step.

`StepBatcher.run(max_steps, until_us)` does what `max_steps` calls of PythonAgent.step() would do (a
program step, then the link's tick), stopping early once agent time reaches until_us. Held modes run
in one compiled call per batch (onboard_batch_kernel.py); a batch returns to Python for whatever the
Python program must do itself (a mode event, a dive limit, a HEARTBEAT), which then finishes the step
exactly as OnboardProgram.step would. The wire bytes of a batch go out in one write.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from learning.config import LearnerConfig
from learning.learner import LearnerArrays
from learning.spec import direct_entry
from protocol import Mode
from simulator.agent import batch_kernel as k
from simulator.agent.link import AgentLink
from simulator.agent.program import OnboardProgram

_HELD = (Mode.RECOVERING, Mode.HOVER, Mode.PAUSED)


def _batchable(config: LearnerConfig) -> bool:
    """Whether LEARNING may run in the compiled batch, which sees the sensed depth and velocity and steps by
    action_step_deg alone: a k-step depth difference, the velocity filter and the fine step near a hover (issue 43)
    run step by step in Python instead."""
    return not config.velocity_diff_steps and config.filter_depth_gain == 0.0 and config.fine_step_deg == 0.0
WIRE_BUFFER_BYTES = 64 * 1024  # one batch's frames; bounds its steps (k.SAMPLE_WIRE bytes each)
_MAX_BATCH_STEPS = WIRE_BUFFER_BYTES // k.SAMPLE_WIRE


class StepBatcher:
    """The registers, wire buffer and compiled entries of one program's batches."""

    def __init__(self, program: OnboardProgram, link: AgentLink) -> None:
        self.program = program
        self.link = link
        self.ints = np.zeros(k.N_INTS, np.int64)
        self.floats = np.zeros(k.N_FLOATS)
        self.wire = np.zeros(WIRE_BUFFER_BYTES, np.uint8)
        self._wire_view = memoryview(self.wire)  # type: ignore[arg-type]  # numpy arrays are buffers
        battery = program.hw.battery
        self.socs = np.array([soc for soc, _ in battery.params.curve])
        self.volts = np.array([volts for _, volts in battery.params.curve])
        plant_state, sensor_rng, spec = program.hw.kernel_state
        ring = link.ring
        self._held_args = (
            self.ints, self.floats, plant_state, program.observer.state, program.recovery.state, sensor_rng,
        )
        self._tables = (self.socs, self.volts, ring.data, ring.index, ring.counters, self.wire)
        self._held = direct_entry(k.held_steps, *self._held_args, True, spec, *self._tables)
        self._learning_args = (self.ints, self.floats, plant_state, program.observer.state, sensor_rng)
        self._learning: dict[type, Callable[..., None]] = {}  # by learner spec type (all learners share one)
        self._learning_entry(program.learner.arrays)  # compiled (or loaded) now, not in the first episode

    def run(self, max_steps: int, until_us: int) -> int:
        """Up to max_steps steps, each a program step and a link tick, until agent time reaches until_us."""
        program, link = self.program, self.link
        program.finish_command()  # a learner restart a command asked for, before any batch uses the learner
        done = 0
        while done < max_steps and program.hw.t_us < until_us:
            mode = program.mode
            if mode in _HELD:
                done += self._held_batch(max_steps - done, until_us)
            elif mode == Mode.LEARNING and _batchable(program.config):
                done += self._learning_batch(max_steps - done, until_us)
            else:
                program.step()
                done += 1
            link.tick()
        return done

    def _held_batch(self, max_steps: int, until_us: int) -> int:
        program, ints, floats = self.program, self.ints, self.floats
        hw, params = program.hw, program.params
        self._load(min(max_steps, _MAX_BATCH_STEPS), until_us, params.recovery_period_s)
        floats[k.HOLD_M] = program._hold_depth_m
        self._held(*self._held_args, params.use_observer, hw.kernel_state[2], *self._tables)
        steps = int(ints[k.STEPS_RUN])
        self._store(steps)
        status = ints[k.STATUS]
        if status == k.SETTLED or status == k.GAVE_UP:
            program.held_sampled(status == k.SETTLED, status == k.GAVE_UP)
        if status != k.DONE:
            program.finish_step(params.recovery_period_s)
        return steps

    def _learning_batch(self, max_steps: int, until_us: int) -> int:
        program, ints, floats = self.program, self.ints, self.floats
        params, learner = program.params, program.learner
        self._load(min(max_steps, _MAX_BATCH_STEPS), until_us, params.control_period_s)
        ints[k.PREV_STATE] = program._prev_state
        ints[k.PREV_ACTION] = program._prev_action
        ints[k.EVICTIONS] = 0
        ints[k.OBSERVED] = 0
        ints[k.TERMINAL] = program._terminal
        ints[k.STEP_LIMIT] = round(params.episode_limit_s / params.control_period_s)
        floats[k.RETURN] = program._return
        floats[k.P_EXPLORE] = learner.p_explore
        floats[k.CENTER_DEG] = program._center_deg
        floats[k.WINDOW_DEG] = params.action_window_deg
        floats[k.ACTION_STEP_DEG] = params.action_step_deg
        floats[k.TARGET_M] = params.target_depth_m
        arrays = learner.arrays
        entry = self._learning_entry(arrays)
        entry(*self._learning_args, params.use_observer, program.hw.kernel_state[2], *self._tables, *arrays)
        steps = int(ints[k.STEPS_RUN])
        self._store(steps)
        program._prev_state = int(ints[k.PREV_STATE])
        program._prev_action = int(ints[k.PREV_ACTION])
        program._steps = int(ints[k.STEPS])
        program._return = float(floats[k.RETURN])
        learner.evictions += int(ints[k.EVICTIONS])
        if ints[k.OBSERVED]:
            program.down.model_changed()
        status = ints[k.STATUS]
        if status == k.EPISODE_OVER:
            program.learning_over(int(ints[k.LAST_STATE]))
        if status != k.DONE:
            program.finish_step(params.control_period_s)
        return steps

    def _learning_entry(self, arrays: LearnerArrays) -> Callable[..., None]:
        entry = self._learning.get(type(arrays.spec))
        if entry is None:
            entry = self._learning[type(arrays.spec)] = direct_entry(
                k.learning_steps, *self._learning_args, True, self.program.hw.kernel_state[2], *self._tables, *arrays
            )
        return entry

    def _load(self, max_steps: int, until_us: int, dt_s: float) -> None:
        """The registers from the program, its hardware and its link."""
        program, link, ints, floats = self.program, self.link, self.ints, self.floats
        hw, mission = program.hw, program.mission
        ints[k.T_US] = hw.t_us
        ints[k.NEXT_SAMPLE] = program.next_sample
        ints[k.SEQ] = link.next_seq
        ints[k.EPISODE] = program.episode
        ints[k.STEPS] = program._steps
        ints[k.MODE] = int(program.mode)
        ints[k.WIRE_END] = 0
        ints[k.HEARTBEAT_DUE_US] = link.heartbeat_due_us
        ints[k.UNTIL_US] = min(until_us, 2**62)
        ints[k.DIVE_START_US] = program._dive_start_us
        ints[k.DT_US] = int(round(dt_s * 1e6))  # as SimulatedHardware.advance counts it
        ints[k.MAX_STEPS] = max_steps
        ints[k.LINK_CHECK] = k.LINK_IGNORED
        if mission.surface_on_link_loss and mission.link_timeout_s:
            if link.uses_agent_clock:
                ints[k.LINK_CHECK] = k.LINK_AGENT_CLOCK
            elif link.link_silence_s() >= mission.link_timeout_s:
                # A wall link clock is read once per batch (a batch lasts well under a millisecond of it).
                ints[k.LINK_CHECK] = k.LINK_LOST
        floats[k.CMD_DEG] = hw.actuator_cmd_deg
        floats[k.CHARGE] = hw.battery.charge_fraction
        floats[k.LOW_BATTERY_V] = mission.low_battery_v
        floats[k.MAX_DIVE_S] = mission.max_dive_s
        floats[k.ENDURANCE_S] = hw.battery.params.endurance_s
        floats[k.DT_S] = dt_s
        floats[k.LINK_TIMEOUT_S] = mission.link_timeout_s
        floats[k.LAST_RX_S] = link.last_ground_rx_s

    def _store(self, steps: int) -> None:
        """The registers back into the program, its hardware and its link; the batch's frames onto the link."""
        if not steps:
            return
        program, link, ints, floats = self.program, self.link, self.ints, self.floats
        hw = program.hw
        hw.t_us = int(ints[k.T_US])
        program.next_sample = int(ints[k.NEXT_SAMPLE])
        hw.plant.alpha_cmd_deg = float(floats[k.CMD_DEG])
        hw.battery.charge_fraction = float(floats[k.CHARGE])
        program.pressure_pa = float(floats[k.PRESSURE_PA])
        program.depth_m = float(floats[k.DEPTH_M])
        program.velocity_mps = float(floats[k.VELOCITY_MPS])
        link.encoder.take_seqs(steps)
        link.write(self._wire_view[: ints[k.WIRE_END]].tobytes())
