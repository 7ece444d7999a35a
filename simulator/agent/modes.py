"""The on-board mode machine, written as the Teensy firmware's modes.c: one control step per call, a state table.

Each step reads only the pressure sensor, estimates the velocity with the sliding mode observer and
drives only the actuator (hardware in hardware.py). The ground's commands that move it between modes are
program.py's. Modes (SPEC.md section 6):

| mode       | period     | each step                                    | leaves to (when)                          |
|------------|------------|----------------------------------------------|-------------------------------------------|
| IDLE       | control    | actuator at neutral; SAMPLE at 1 Hz          | RECOVERING (CMD_START); HOVER (CMD_HOVER)  |
| RECOVERING | recovery   | recovery controller to a random start depth  | LEARNING (settled: EPISODE_START);         |
|            |            |                                              | SURFACING (not settled after give_up_s)    |
| LEARNING   | control    | the learner acts, observes, is rewarded      | RECOVERING (failure or success:            |
|            |            |                                              | EPISODE_END); SURFACING (episode limit);   |
|            |            |                                              | PAUSED (CMD_PAUSE: EPISODE_END aborted)    |
| HOVER      | recovery   | recovery controller holds the hover depth    | RECOVERING (CMD_START); SURFACING (STOP)   |
| PAUSED     | recovery   | recovery controller holds the paused depth   | RECOVERING (CMD_START); SURFACING (STOP)   |
| SURFACING  | control    | actuator at maximum volume                   | IDLE (shallower than surface_depth_m)      |

Periods: control = control_dt_s (0.1 s), recovery = the recovery controller's 0.025 s.

In every mode but IDLE and SURFACING: battery below low_batt_v, max_dive_s away from IDLE, or link
loss with surface_on_link_loss -> SURFACING (an episode in progress ends ABORTED). CMD_SURFACE works in
every mode. With start_at_rest (the `paper` preset; simulator only) RECOVERING places the agent at rest
at its start depth at once, as the paper's simulation restarts episodes.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from learning import Learner, LearnerConfig, n_states
from learning.acting import reward_kernel, state_index_kernel, step_size_kernel
from learning.config import kernel_spec
from learning.errors import LearnerConfigError
from learning.shared import raw_cell_kernel
from learning.spec import direct_entry
from protocol import Action, EndReason, Mode, Severity, messages
from protocol.registry import Message
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.identity import FIRST_GENERATION
from simulator.agent.kernel import recovery_period_kernel, sense_kernel
from simulator.agent.mission import MissionConfig
from simulator.parameters import PlantParams
from simulator.plant.observer import DepthDifference, SlidingModeObserver, VelocityFilter
from simulator.plant.recovery import RecoveryController

_DIVING = (Mode.RECOVERING, Mode.LEARNING, Mode.HOVER, Mode.PAUSED)
_HELD = (Mode.RECOVERING, Mode.HOVER, Mode.PAUSED)  # the recovery controller holds a depth
_SAMPLE_ID = messages.Sample.MSG_ID
_pack_sample = messages.Sample.pack_values


class Downlink(Protocol):
    """Where the program's frames go (the link layer): logged frames also enter the on-board log."""

    def log_frame(self, message: Message, sample: int, is_sample: bool) -> None: ...

    def log_payload(self, msg_id: int, payload: bytes, sample: int, is_sample: bool) -> None: ...

    def send(self, message: Message) -> None: ...

    def episode_dumps(self) -> None: ...

    def link_silence_s(self) -> float: ...

    def model_changed(self) -> None: ...


class ModeMachine:
    """The firmware's main loop state: mode, learner, controllers, episode bookkeeping."""

    def __init__(
        self, params: PlantParams, learner_config: LearnerConfig, mission: MissionConfig,
        hw: SimulatedHardware, rng: np.random.Generator, downlink: Downlink,
    ) -> None:
        self.hw = hw
        self.rng = rng
        self.down = downlink
        self.params, self.config, self.mission = params, learner_config, mission
        self.learner = Learner(learner_config, rng)
        self._bind_learner(learner_config)
        self.observer = SlidingModeObserver(params)
        self.recovery = RecoveryController(params)
        # One compiled call per sensing / recovery period instead of one per kernel (kernel.py).
        plant_state, sensor_rng, spec = hw.kernel_state
        self._sense_args = (plant_state, self.observer.state, sensor_rng)
        self._spec = spec
        self._sense = direct_entry(sense_kernel, *self._sense_args, True, 0.0, spec)
        self._recovery_args = (plant_state, self.observer.state, self.recovery.state, sensor_rng)
        self._recovery_period = direct_entry(recovery_period_kernel, *self._recovery_args, True, 0.0, 0.0, spec)
        self.mode = Mode.IDLE
        self.next_sample = 0
        self.depth_m = 0.0
        self.velocity_mps = 0.0
        self.pressure_pa = hw.read_pressure_pa()
        self.successes = 0
        self.generation = FIRST_GENERATION  # SPEC 1.3 s. 6: +1 at every learner restart
        self.episodes_left = 0  # 0 = no limit
        self._dive_start_us = 0
        self._hold_depth_m = 0.0  # recovery / hover / pause set point
        self._next_idle_sample_us = 0
        self._restart_pending = ""  # the parameter (set by program.py) whose change restarts the learner, or ""
        self._reset_episode()

    # ------------------------------------------------------------------ main loop
    def step(self) -> None:
        """One control step of the current mode, then let its period of agent time pass."""
        self.finish_command()  # at the latest here (the server runs it once the ACK has left, see serve/loop.py)
        mode = self.mode
        if mode == Mode.LEARNING:
            dt = self.params.control_period_s
            self._learning_step(dt)
        elif mode in _HELD:
            dt = self.params.recovery_period_s
            self._controller_step(dt)
        elif mode == Mode.SURFACING:
            dt = self.params.control_period_s
            self._measure(dt)
            self.hw.set_actuator_cmd_deg(self.params.alpha_max_deg)
            self._sample(Action.NONE, 0.0, 0)
            if self.depth_m < self.mission.surface_depth_m:
                self._enter(Mode.IDLE, "at the surface")
        else:
            dt = self.params.control_period_s
            self._measure(dt)
            self.hw.set_actuator_cmd_deg(self.hw.neutral_deg)
            if self.hw.t_us >= self._next_idle_sample_us:
                self._next_idle_sample_us = self.hw.t_us + int(self.mission.idle_sample_period_s * 1e6)
                self._sample(Action.NONE, 0.0, 0)
        self.finish_step(dt)

    def finish_step(self, dt: float) -> None:
        """The end of every step: the dive limits, then dt of agent time passes (also after a compiled batch)."""
        if self.mode in _DIVING:
            self._check_limits()
        self.hw.advance(dt)

    def _bind_learner(self, config: LearnerConfig) -> None:
        """The compiled per-step learner kernels of this config, and its velocity input."""
        if max(config.hold_depth_m, config.hold_speed_mps, config.hold_lash_deg, config.neutral_gain) > 0.0:
            # Screened in the study only (docs/learners-hold.md): no agent parameter, so the agent would ignore them.
            raise LearnerConfigError("hold_depth_m, hold_speed_mps, hold_lash_deg and neutral_gain are study options: "
                                     "the agents have no parameter for them")
        self._lspec = kernel_spec(config)
        self._state_index = direct_entry(state_index_kernel, 0.0, 0.0, 0.0, 0.0, self._lspec)
        self._raw_cell = direct_entry(raw_cell_kernel, 0.0, 0.0, 0.0, 0.0, self._lspec)
        self._reward = direct_entry(reward_kernel, 0.0, 0.0, 0, self._lspec)
        self._step_size = direct_entry(step_size_kernel, 0.0, 0.0, False, self._lspec)
        self._terminal = n_states(config) - 1
        self._depth_difference = (
            DepthDifference(config.velocity_diff_steps) if config.velocity_diff_steps else None
        )
        self._velocity_filter = VelocityFilter(config) if config.filter_depth_gain > 0.0 else None

    @property
    def t_us(self) -> int:
        return self.hw.t_us

    def _measure(self, dt_s: float) -> None:
        # The paper preset feeds the learner the true velocity (its simulation did; diving-agent.md s. 7).
        self.pressure_pa, self.depth_m, self.velocity_mps = self._sense(
            *self._sense_args, self.params.use_observer, dt_s, self._spec
        )

    def _learner_depth_m(self) -> float:
        """The depth the learner sees: its filter's estimate (LearnerConfig.filter_depth_state) or the reading."""
        if self._velocity_filter is not None and self.config.filter_depth_state:
            return self._velocity_filter.depth_m
        return self.depth_m

    def _state(self) -> int:
        fraction = (self.hw.actuator_cmd_deg - self._center_deg) / self.params.action_window_deg
        return int(self._state_index(
            self._learner_depth_m(), self.velocity_mps, self.params.target_depth_m, fraction, self._lspec
        ))

    def _sample(self, action: int, reward: float, state: int) -> None:
        index = self.next_sample
        self.next_sample = index + 1
        hw = self.hw
        # Packed from the values in messages.Sample's field order: the same bytes as building the message.
        self.down.log_payload(_SAMPLE_ID, _pack_sample(
            hw.t_us, index, self.episode, self._steps, self.pressure_pa, self.depth_m, self.velocity_mps,
            hw.actuator_deg, hw.actuator_cmd_deg, reward, state, action, self.mode,
        ), index, True)

    def text(self, line: str, severity: Severity = Severity.INFO) -> None:
        self.down.send(messages.Text(t_us=self.hw.t_us, severity=int(severity), text=line[:238]))

    # ------------------------------------------------------------------ modes
    def _enter(self, mode: Mode, why: str) -> None:
        if mode == self.mode:
            return
        if self.mode == Mode.IDLE:
            self._dive_start_us = self.hw.t_us
        self.text(f"mode {self.mode.name} -> {mode.name}: {why}")
        self.mode = mode
        if mode in _HELD:
            self.recovery.restart()
        if mode == Mode.RECOVERING:
            half_m = self.params.start_depth_fraction * self.config.z_tol_m
            self._hold_depth_m = self.params.target_depth_m + half_m * float(self.rng.uniform(-1.0, 1.0))
            if not self.params.start_with_recovery:
                self._center_deg = self.hw.place(self._hold_depth_m)
                self.observer.reset(self._hold_depth_m)
                self._measure(0.0)
                self._begin_episode(self._center_deg)

    def _controller_step(self, dt: float) -> None:
        self.pressure_pa, self.depth_m, self.velocity_mps, cmd, settled, gave_up = self._recovery_period(
            *self._recovery_args, self.params.use_observer, self._hold_depth_m, dt, self._spec
        )
        self.hw.set_actuator_cmd_deg(cmd)
        self._sample(Action.NONE, 0.0, 0)
        self.held_sampled(settled, gave_up)

    def held_sampled(self, settled: bool, gave_up: bool) -> None:
        """What a held step does after its SAMPLE: RECOVERING hands over to the learner or gives up."""
        if self.mode == Mode.RECOVERING:
            if settled:
                self._begin_episode(self.recovery.alpha_avg_deg + self.params.start_trim_error_deg)
            elif gave_up:
                self._enter(Mode.SURFACING, "recovery did not settle")

    def _check_limits(self) -> None:
        mission, hw = self.mission, self.hw
        why = ""
        if hw.battery_v < mission.low_battery_v:
            why = f"battery low ({hw.battery_v:.2f} V)"
        elif mission.max_dive_s and hw.t_us - self._dive_start_us >= mission.max_dive_s * 1e6:
            why = "maximum dive time"
        elif (mission.surface_on_link_loss and mission.link_timeout_s
              and self.down.link_silence_s() >= mission.link_timeout_s):
            why = "link lost"
        if why:
            self.surface(why)

    def surface(self, why: str) -> None:
        self._abort_episode()
        self._enter(Mode.SURFACING, why)

    # ------------------------------------------------------------------ learning episodes
    def _reset_episode(self) -> None:
        self.episode = self.learner.episode
        self._steps = 0
        self._return = 0.0
        self._prev_state = -1
        self._prev_action = 0
        self._center_deg = self.hw.neutral_deg

    def _begin_episode(self, center_deg: float) -> None:
        self._reset_episode()
        self.episode = self.learner.episode + 1
        self._center_deg = center_deg
        self.hw.set_actuator_cmd_deg(center_deg)
        if self._depth_difference is not None:
            self._depth_difference.reset(self.depth_m)
            self.velocity_mps = 0.0
        if self._velocity_filter is not None:
            self._velocity_filter.reset(self.depth_m)
            self.velocity_mps = 0.0
        start_state = self._state()
        self.text(f"mode {self.mode.name} -> LEARNING: episode {self.episode}")
        self.mode = Mode.LEARNING
        c = self.config
        self.down.log_frame(messages.EpisodeStart(
            t_us=self.hw.t_us, episode=self.episode, sample=self.next_sample, start_state=start_state,
            depth_m=self.depth_m, velocity_mps=self.velocity_mps, target_depth_m=self.params.target_depth_m,
            z_tol_m=c.z_tol_m, zdot_tol_mps=c.zdot_tol_mps, p_explore=self.learner.p_explore,
            generation=self.generation,
        ), self.next_sample, False)

    def _learning_step(self, dt: float) -> None:
        self._measure(dt)
        if self._depth_difference is not None:
            self.velocity_mps = self._depth_difference.update(self.depth_m, dt)
        elif self._velocity_filter is not None:
            offset_deg = self.hw.actuator_cmd_deg - self._center_deg  # the command of the period just ended
            self.velocity_mps = self._velocity_filter.update(self.depth_m, offset_deg, dt)
        state = self._state()
        reward = 0.0
        if self._prev_state >= 0:
            reward = float(self._reward(self._learner_depth_m(), self.params.target_depth_m, state, self._lspec))
            self._return += reward
            cell = None
            if self.config.shared_model:
                fraction = (self.hw.actuator_cmd_deg - self._center_deg) / self.params.action_window_deg
                cell = int(self._raw_cell(
                    self._learner_depth_m(), self.velocity_mps, self.params.target_depth_m, fraction, self._lspec
                ))
            self.learner.observe(self._prev_state, self._prev_action, reward, state, cell)
            self.down.model_changed()
        limit = round(self.params.episode_limit_s / self.params.control_period_s)
        if state == self._terminal or self._steps >= limit:
            self._sample(Action.NONE, reward, state)
            self.learning_over(state)
            return
        action = self.learner.act(state)
        reversal = self._prev_state < 0 or action != self._prev_action  # the episode's first action counts as one
        size = float(self._step_size(self.velocity_mps, self.params.action_step_deg, reversal, self._lspec))
        step = size if action == Action.INCREASE_VOLUME else -size
        window = self.params.action_window_deg
        cmd = min(max(self.hw.actuator_cmd_deg + step, self._center_deg - window), self._center_deg + window)
        self.hw.set_actuator_cmd_deg(cmd)
        self._prev_state, self._prev_action = state, action
        self._sample(action, reward, state)
        self._steps += 1

    def learning_over(self, state: int) -> None:
        """After the last SAMPLE of an episode: it failed (left the region) or succeeded (lasted its time)."""
        self._end_episode(EndReason.FAILURE if state == self._terminal else EndReason.SUCCESS, state)

    def _end_episode(self, reason: EndReason, state: int) -> None:
        self.learner.end_episode()
        if reason == EndReason.SUCCESS:
            self.successes += 1
        self.down.log_frame(messages.EpisodeEnd(
            t_us=self.hw.t_us, episode=self.episode, sample=self.next_sample - 1, reason=int(reason),
            end_state=state, steps=self._steps, duration_s=self._steps * self.params.control_period_s,
            episode_return=self._return, successes=self.successes, generation=self.generation,
        ), self.next_sample - 1, False)
        if self.mission.dump_each_episode:
            self.down.episode_dumps()
        if reason == EndReason.ABORTED:
            return
        if self.episodes_left:
            self.episodes_left -= 1
            if self.episodes_left == 0:
                self._enter(Mode.SURFACING, "episode limit reached")
                return
        self.mode = Mode.LEARNING  # so that _enter logs the hand-back and picks a new start
        self._enter(Mode.RECOVERING, f"episode {self.episode} {reason.name.lower()}")

    def _abort_episode(self) -> None:
        if self.mode == Mode.LEARNING:
            self._end_episode(EndReason.ABORTED, self._state())

    # ------------------------------------------------------------------ after a command's ACK
    @property
    def restart_pending(self) -> bool:
        return bool(self._restart_pending)

    def finish_command(self) -> None:
        """What a command caused that may take long, run once its ACK is out (SPEC s. 5: the ACK comes before
        anything the command causes): a new learner compiles its kernels on first use, seconds on a cold cache."""
        name, self._restart_pending = self._restart_pending, ""
        if not name:
            return
        self.learner = Learner(self.config, self.rng)
        self._bind_learner(self.config)
        self.restarted_learner(f"{name} changed: learner restarted")

    def restarted_learner(self, why: str) -> None:
        """A new learner (any cause): a new generation, its episodes numbered from 1 again (SPEC 1.3 s. 6)."""
        self.generation = (self.generation + 1) & 0xFFFFFFFF
        self.down.model_changed()
        self.successes = 0
        self._reset_episode()
        self.text(f"{why}, generation {self.generation}")

