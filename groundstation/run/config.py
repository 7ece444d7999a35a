"""What `dive run` is told: the agent's link, the episodes, the parameters to set, the recorder, alarms and history."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from groundstation.recording.recorder import RecorderConfig
from groundstation.run.alarms import AlarmConfig
from groundstation.run.history import HistoryConfig
from groundstation.session.agent_session import SessionConfig

DUMP_EACH_EPISODE_NAMES = ("dump_each_episode", "dump_each_ep")  # SPEC 1.1's name, and the agents' older one


def load_params_file(path: Path) -> dict[str, str]:
    """Parameters from a TOML file of `name = value` lines (groundstation/session/paramfile.py)."""
    from groundstation.session.paramfile import read_params

    return read_params(path)


@dataclass(frozen=True, slots=True)
class RunConfig:
    url: str | None = None
    episodes: int = 0  # 0 = until stopped
    params: dict[str, str] = field(default_factory=dict)
    recorder: RecorderConfig = field(default_factory=RecorderConfig)
    session: SessionConfig = field(default_factory=SessionConfig)
    backfill_wait_s: float = 10.0
    hub: bool = True  # serve the session to local tools (groundstation/run/hub.py)
    # The agent sends VALUES and POLICY after every episode, with or without a viewer: every recording replays
    # whole (the heatmaps fill from these) and a tool attaching late gets the last ones (run/history.py).
    dumps_each_episode: bool = True
    alarms: AlarmConfig = field(default_factory=AlarmConfig)
    history: HistoryConfig = field(default_factory=HistoryConfig)  # what a tool attaching late is given first
