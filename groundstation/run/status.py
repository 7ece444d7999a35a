"""What a run shows and returns: its status (episodes, link, the agent's status line, alarms) and its result."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from groundstation.links.runs import RunInfo
from groundstation.session.status_line import AgentStatus

ECHO = "> "  # how the run pane's echo of a command, marker or acknowledgement begins (cli/progress.py styles it)


@dataclass
class RunStatus:
    """What the progress display shows; updated from the session's reader thread."""

    episodes: int = 0
    successes: int = 0
    failures: int = 0
    last_duration_s: float | None = None
    last_reason: str = ""
    samples: int = 0
    link_up: bool = False
    link: dict[str, Any] = field(default_factory=dict)
    messages: list[str] = field(default_factory=list)
    hub: str = ""  # hub://RUN once local tools can attach
    ends: list[tuple[int, str, float]] = field(default_factory=list)  # (episode, outcome, duration s) in order
    # Learner restarts (SPEC 1.3 s. 6): the index into `ends` where each chapter after the first begins, and its
    # number; the agent numbers the new chapter's episodes from 1, the run counts on (completed, --episodes).
    chapter_starts: list[tuple[int, int]] = field(default_factory=list)
    agent: AgentStatus = field(default_factory=AgentStatus)  # what the status line shows of the agent
    alarm_flag: str = ""  # the status line's alarm field (run/alarms.py: until acknowledged)
    stopped: str = ""  # what the run found the agent doing when it was stopped, and what it did about it

    @property
    def completed(self) -> int:
        """Episodes that used the run's budget: an aborted one (a pause, a surface) does not, as on the agent."""
        return self.successes + self.failures


@dataclass(frozen=True, slots=True)
class RunResult:
    paths: list[Path]
    status: RunStatus
    interrupted: bool
    still_missing: int
    lost: int = 0  # of still_missing: samples the agent's log no longer held (proved by its LOG_RANGE / HEARTBEAT)
    announced: RunInfo | None = None  # how the run was last announced to the machine's other tools (links/runs.py)
    tools_dropped: int = 0  # tools the hub dropped for falling a whole queue behind (run/hub_outbox.py)
