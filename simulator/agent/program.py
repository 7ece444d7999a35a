"""The on-board program: the mode machine (modes.py) answering the ground's commands with a verdict each.

Each command (SPEC.md sections 5-6, PARAM_SET section 13) checks its values, then the mode, and only then acts;
what may take long (a learner restart) waits for the ACK (ModeMachine.finish_command).
"""

from __future__ import annotations

import numpy as np

from learning import LearnerConfig
from protocol import AckResult, Mode
from simulator.agent.hardware import SimulatedHardware
from simulator.agent.mission import MissionConfig
from simulator.agent.modes import Downlink, ModeMachine
from simulator.agent.params_table import ParamTable, Scope, check_ram
from simulator.errors import ParamsError
from simulator.parameters import PlantParams

__all__ = ["Downlink", "OnboardProgram", "Scope", "Verdict"]

Verdict = tuple[AckResult, str]
OK: Verdict = (AckResult.ACCEPTED, "")


def _not_allowed(mode: Mode) -> Verdict:
    return AckResult.NOT_ALLOWED_IN_MODE, f"not allowed in {mode.name}"


class OnboardProgram(ModeMachine):
    """The firmware's main loop with its command handlers and the parameter table they set."""

    def __init__(
        self, params: PlantParams, learner_config: LearnerConfig, mission: MissionConfig,
        hw: SimulatedHardware, rng: np.random.Generator, downlink: Downlink,
    ) -> None:
        super().__init__(params, learner_config, mission, hw, rng, downlink)
        self.table = ParamTable({Scope.LEARNER: learner_config, Scope.PLANT: params, Scope.MISSION: mission})
        self._base = (params, learner_config, mission)  # what the table's values apply to

    def start(self, max_episodes: int) -> Verdict:
        if self.mode not in (Mode.IDLE, Mode.HOVER, Mode.PAUSED):
            return _not_allowed(self.mode)
        self.episodes_left = max_episodes or self.mission.max_episodes
        self._enter(Mode.RECOVERING, "CMD_START")
        return OK

    def stop(self) -> Verdict:
        if self.mode not in (Mode.IDLE, Mode.SURFACING):  # SPEC s. 6: accepted in IDLE and SURFACING, no change
            self.surface("CMD_STOP")
        return OK

    def pause(self) -> Verdict:
        if self.mode not in (Mode.LEARNING, Mode.RECOVERING):
            return _not_allowed(self.mode)
        self._abort_episode()
        self._hold_depth_m = self.depth_m
        self._enter(Mode.PAUSED, "CMD_PAUSE")
        return OK

    def hover(self, depth_m: float) -> Verdict:
        if not 0.0 <= depth_m <= 2.5 or depth_m != depth_m:
            return AckResult.BAD_VALUE, "hover depth outside [0, 2.5] m"
        if self.mode not in (Mode.IDLE, Mode.HOVER, Mode.PAUSED):
            return _not_allowed(self.mode)
        self._hold_depth_m = depth_m
        self._enter(Mode.HOVER, f"CMD_HOVER at {depth_m:.2f} m")
        return OK

    def reset_model(self) -> Verdict:
        if self.mode == Mode.LEARNING:
            return _not_allowed(self.mode)
        self.learner.reset()
        self.restarted_learner("model reset: learner restarted")
        return OK

    def set_param(self, index: int, value: float) -> Verdict:
        """Apply a parameter (SPEC.md section 13): value checks, then the mode; a learner change restarts it."""
        definition = self.table.defs[index]
        old = self.table.values[index]
        try:
            self.table.set(index, value)
            params, config, mission = self._base
            new_config = self.table.apply(Scope.LEARNER, config)
            new_params = self.table.apply(Scope.PLANT, params)
            new_mission = self.table.apply(Scope.MISSION, mission)
            if definition.learner:
                check_ram(new_config)
        except (ParamsError, ValueError) as e:  # LearnerConfigError is a ValueError too
            self.table.values[index] = old
            return AckResult.BAD_VALUE, str(e)
        if self.mode in definition.refused_in:
            self.table.values[index] = old
            return _not_allowed(self.mode)
        self.params, self.mission = new_params, new_mission
        # SPEC 1.2 s. 13: a change is a different stored value; the current one again restarts nothing.
        if definition.learner and self.table.values[index] != old and new_config != self.config:
            self.config = new_config
            self._restart_pending = definition.name
        return OK
