"""The operator's status line: mode, episode, successes, battery, depth, link RTT and loss, from a session's frames."""

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
    # Every EPISODE_END so far has reached this status (a tool given the run's episode table by its hub): no
    # successes then means no episode has ended, not that none was seen while watching.
    ends_known: bool = False

    def update(self, message: object) -> None:
        if isinstance(message, m.Heartbeat):
            self.mode, self.episode, self.battery_mv = message.mode, message.episode, message.battery_mv
            self.uptime_ms = message.uptime_ms
        elif isinstance(message, m.Sample):
            self.depth_m = message.depth_m
        elif isinstance(message, m.EpisodeEnd):
            self.successes = message.successes


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


def status_line(agent: AgentStatus, link: dict[str, Any], link_up: bool = True) -> str:
    """One line: `LEARNING | episode 12 | 9 ok | 4.15 V | depth 0.41 m | rtt 25 ms, loss 0.0%`."""
    def known(value: object, text: str) -> str:
        return text if value is not None else "-"

    rtt = link.get("rtt_median_ms")
    quality = (f"rtt {rtt:.0f} ms, " if rtt is not None else "rtt -, ") + \
        f"loss {100 * float(link.get('loss_fraction', 0.0)):.1f}%"
    parts = [mode_text(agent.mode), f"episode {known(agent.episode, str(agent.episode))}",
             successes_text(agent),
             known(agent.battery_mv, f"{(agent.battery_mv or 0) / 1000:.2f} V"),
             f"depth {known(agent.depth_m, f'{round(agent.depth_m or 0.0, 2) + 0.0:.2f} m')}",  # never -0.00
             quality if link_up else "link down"]
    return " | ".join(parts)
