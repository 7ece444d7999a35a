"""The run's listener that counts episodes (each EPISODE_END once, across learner restarts) and fills its status."""

from __future__ import annotations

import threading

from groundstation.run.learner_restarts import LearnerRestarts
from groundstation.run.status import ECHO, RunStatus
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import EndReason
from protocol import messages as m


class Progress:
    """A session listener that counts episodes and keeps the latest link statistics."""

    def __init__(self, status: RunStatus) -> None:
        self.status = status
        self.changed = threading.Event()
        # Each EPISODE_END once, live or backfilled: by (generation, episode, its last sample), as a learner
        # restart numbers episodes from 1 again (a 1.2 agent's generation is 0; the sample index still differs).
        self._episodes: set[tuple[int, int, int]] = set()
        self.restarts = LearnerRestarts()

    def on_received(self, received: Received) -> None:
        msg = received.message
        if not received.backfilled:
            self.status.agent.update(msg)
            line = self.restarts.received(msg)
            if line is not None:
                self.status.chapter_starts.append((len(self.status.ends), self.restarts.chapter.number))
                self.status.messages.append(line)
                self.changed.set()
        if isinstance(msg, m.Sample):
            self.status.samples += 1
        elif isinstance(msg, m.EpisodeEnd) and (msg.generation, msg.episode, msg.sample) not in self._episodes:
            self._episodes.add((msg.generation, msg.episode, msg.sample))
            s = self.status
            s.episodes += 1
            s.successes += msg.reason == EndReason.SUCCESS
            s.failures += msg.reason == EndReason.FAILURE
            s.last_duration_s = msg.duration_s
            s.last_reason = EndReason(msg.reason).name.lower() if msg.reason in (1, 2, 3) else str(msg.reason)
            s.ends.append((msg.episode, s.last_reason, msg.duration_s))
            self.changed.set()

    def on_sent(self, sent: Sent) -> None:
        self.restarts.sent(sent.message)

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.STATS:
            self.status.link = event.data.get("link", {})
        elif event.kind in (EventKind.LINK_LOST, EventKind.LINK_RESTORED, EventKind.RESYNCED, EventKind.ERROR):
            self.status.messages.append(f"{event.kind}: {event.detail}")
        elif event.kind in (EventKind.COMMAND, EventKind.ALARM_ACK):
            self.status.messages.append(f"{ECHO}{event.detail}")  # a tool's command (run/echo.py), an acknowledgement
            if event.data.get("accepted") and "target_depth_m" in event.data:
                self.status.agent.target_m = event.data["target_depth_m"]
        elif event.kind == EventKind.MARKER:
            by = event.data.get("by")
            self.status.messages.append(f"{ECHO}{by or 'the run'}: mark {event.detail!r}")
        if event.kind in (EventKind.LINK_LOST, EventKind.LINK_RESTORED, EventKind.CONNECTED):
            self.status.link_up = event.kind != EventKind.LINK_LOST
        self.changed.set()
