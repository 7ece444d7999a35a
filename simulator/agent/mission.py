"""Mission settings of the on-board program (link loss, dive limits, battery, dumps) and the battery model."""

from __future__ import annotations

from bisect import bisect_left
from dataclasses import dataclass


@dataclass(frozen=True)
class MissionConfig:
    """What the on-board program does around learning; every field is a parameter of the agent."""

    link_timeout_s: float = 10.0  # SPEC s. 4: no valid frame for this long = link lost (0 = never)
    # The radio does not reach through water, so by default a lost link does not end a dive.
    surface_on_link_loss: bool = False
    dump_each_episode: bool = False  # SPEC s. 10: VALUES and POLICY unprompted after every episode
    max_dive_s: float = 0.0  # surface after this long away from IDLE (0 = no limit)
    max_episodes: int = 0  # episodes per CMD_START when the command gives 0 (0 = no limit)
    low_battery_v: float = 3.4  # paper / firmware: the agent surfaces below 3.4 V
    surface_depth_m: float = 0.02  # SURFACING ends (-> IDLE) shallower than this
    idle_sample_period_s: float = 1.0  # SPEC s. 7: SAMPLE at 1 Hz in IDLE
    heartbeat_period_s: float = 1.0  # SPEC s. 4: HEARTBEAT about once per second


@dataclass(frozen=True)
class BatteryParams:
    """1S LiPo 1200 mAh that lasts about 2 h (paper); open-circuit voltage by state of charge."""

    capacity_mah: float = 1200.0  # paper
    endurance_s: float = 2.0 * 3600.0  # paper: about 2 h of operation, i.e. a mean draw of 0.6 A
    # Typical 1S LiPo discharge curve (state of charge, volts); 3.4 V is reached when 2 h are used up.
    curve: tuple[tuple[float, float], ...] = (
        (0.0, 3.40), (0.05, 3.55), (0.10, 3.65), (0.20, 3.72), (0.50, 3.82), (0.80, 3.98), (1.0, 4.20),
    )


class Battery:
    """Charge drains linearly with agent time at the mean current implied by the 2 h endurance."""

    def __init__(self, params: BatteryParams | None = None) -> None:
        self.params = params or BatteryParams()
        self.charge_fraction = 1.0
        self._socs = [soc for soc, _ in self.params.curve]

    def drain(self, dt_s: float) -> None:
        self.charge_fraction = max(0.0, self.charge_fraction - dt_s / self.params.endurance_s)

    @property
    def voltage_v(self) -> float:
        """Open-circuit voltage, interpolated on the discharge curve."""
        curve = self.params.curve
        soc = self.charge_fraction
        # The first point at or above soc closes the segment (read every control step, so no scan).
        upper = bisect_left(self._socs, soc, 1)
        if upper == len(curve):
            return curve[-1][1]
        (soc0, v0), (soc1, v1) = curve[upper - 1], curve[upper]
        return v0 + (v1 - v0) * (soc - soc0) / (soc1 - soc0)
