"""The operator's status line: mode, episode, successes, time held, target, depth, battery, link, alarms."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from protocol import Mode
from protocol import messages as m


@dataclass
class AgentStatus:
    """What the agent last said about itself (HEARTBEAT, SAMPLE, EPISODE_END), updated from the reader thread."""

    mode: int | None = None
    episode: int | None = None
    successes: int | None = None
    battery_mv: int | None = None
    depth_m: float | None = None
    uptime_ms: int | None = None
    target_m: float | None = None  # EPISODE_START's, a PARAM_VALUE's, or an accepted CMD_SET_TARGET's
    success_s: float | None = None  # success_time_s: an episode held this long in the region is a success
    held_s: float | None = None  # of the episode learning now (in the region since its EPISODE_START); else None
    _episode_t_us: int | None = None  # the agent time of the current episode's EPISODE_START
    # Every EPISODE_END so far has reached this status (a tool given the run's episode table by its hub): no
    # successes then means no episode has ended, not that none was seen while watching.
    ends_known: bool = False

    def update(self, message: object) -> None:
        if isinstance(message, m.Heartbeat):
            self.mode, self.episode, self.battery_mv = message.mode, message.episode, message.battery_mv
            self.uptime_ms = message.uptime_ms
        elif isinstance(message, m.Sample):
            self.depth_m = message.depth_m
            learning = message.mode == Mode.LEARNING and self._episode_t_us is not None
            self.held_s = (message.t_us - (self._episode_t_us or 0)) / 1e6 if learning else None
        elif isinstance(message, m.EpisodeStart):
            self.target_m, self._episode_t_us, self.held_s = message.target_depth_m, message.t_us, 0.0
        elif isinstance(message, m.EpisodeEnd):
            self.successes = message.successes
            self._episode_t_us = self.held_s = None
        elif isinstance(message, m.ParamValue):
            self.param(message.name, message.value)

    def param(self, name: str, value: float) -> None:
        """A parameter the line shows, as the agent stored it."""
        if name == "target_depth_m":
            self.target_m = value
        elif name == "success_time_s":
            self.success_s = value


def mode_text(mode: int | None) -> str:
    if mode is None:
        return "-"
    return Mode(mode).name if mode in Mode._value2member_map_ else f"mode {mode}"


def successes_text(agent: AgentStatus) -> str:
    """`9 ok`, or what is known when no EPISODE_END (which carries the count) has come."""
    if agent.successes is not None:
        return f"{agent.successes} ok"
    if agent.ends_known or agent.episode == 0:
        return "no episode ended yet"
    return "successes unknown (no episode ended while watching)"


def held_text(agent: AgentStatus) -> str | None:
    """`held 212/300 s` while an episode learns (the time in the region of the success time), else None."""
    if agent.held_s is None:
        return None
    of = f"/{agent.success_s:.0f}" if agent.success_s is not None else ""
    return f"held {max(0.0, agent.held_s):.0f}{of} s"


def status_line(agent: AgentStatus, link: dict[str, Any], link_up: bool = True, alarm: str = "") -> str:
    """One line: `LEARNING | episode 12 | 9 ok | held 212/300 s | target 0.60 m | depth 0.41 m | 4.15 V |
    rtt 25 ms, loss 0.0%`, then the alarm flag when there is one (run/alarms.py: until acknowledged)."""
    def known(value: object, text: str) -> str:
        return text if value is not None else "-"

    rtt = link.get("rtt_median_ms")
    quality = (f"rtt {rtt:.0f} ms, " if rtt is not None else "rtt -, ") + \
        f"loss {100 * float(link.get('loss_fraction', 0.0)):.1f}%"
    held = held_text(agent)
    parts = [mode_text(agent.mode), f"episode {known(agent.episode, str(agent.episode))}",
             successes_text(agent), *([held] if held else []),
             *([f"target {agent.target_m:.2f} m"] if agent.target_m is not None else []),
             f"depth {known(agent.depth_m, f'{round(agent.depth_m or 0.0, 2) + 0.0:.2f} m')}",  # never -0.00
             known(agent.battery_mv, f"{(agent.battery_mv or 0) / 1000:.2f} V"),
             quality if link_up else "link down", *([alarm] if alarm else [])]
    return " | ".join(parts)
