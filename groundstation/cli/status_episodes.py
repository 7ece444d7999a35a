"""What `dive status` knows of the episodes: the live EPISODE_ENDs, and through a run's hub the run's episode table."""

from __future__ import annotations

import threading
import time

from groundstation.session.agent_session import Session
from groundstation.session.events import Received
from groundstation.session.status_line import AgentStatus
from protocol import EndReason
from protocol import messages as m


class StatusEpisodes:
    """A HEARTBEAT does not carry the successes; an EPISODE_END does, and one comes only when an episode ends.

    Through a run's hub, the run's history (run/history.py: every EPISODE_END of the run) is asked for, as `dive
    view` does. Of its replay only the EPISODE_ENDs are used (its old SAMPLEs must not pass for the depth now), the
    newest last; a live EPISODE_END is newer than any of them.
    """

    def __init__(self, agent: AgentStatus) -> None:
        self.agent = agent
        self.last_end: m.EpisodeEnd | None = None
        self._live_end = False
        self._asked = False
        self._replayed = threading.Event()

    def received(self, received: Received) -> None:
        """The session's listener (its reader thread)."""
        msg = received.message
        if not received.backfilled:
            self.agent.update(msg)
        if isinstance(msg, m.EpisodeEnd) and not (received.backfilled and self._live_end):
            self.last_end, self._live_end = msg, not received.backfilled
            self.agent.successes = msg.successes
        elif isinstance(msg, m.LogRange):  # the end of the hub's replay
            self._replayed.set()

    def ask(self, s: Session) -> None:
        """Ask a run's hub for its history (never an agent: it would replay its on-board log over its one link)."""
        self._asked = True
        s.command(m.LogRequest(first_sample=0, end_sample=0xFFFFFFFF))

    def wait(self, deadline: float) -> None:
        """Until the replay asked for has ended (its LOG_RANGE), at the latest `deadline` (time.monotonic)."""
        if self._asked and self._replayed.wait(max(0.0, deadline - time.monotonic())):
            self.agent.ends_known = True

    def last_end_text(self) -> str:
        end = self.last_end
        assert end is not None
        reason = EndReason(end.reason).name.lower() if end.reason in EndReason._value2member_map_ else str(end.reason)
        return f"last episode ended: {end.episode} ({reason}, {end.duration_s:.1f} s in the region)"
