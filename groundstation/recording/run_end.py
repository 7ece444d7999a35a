"""A recording made through a run's hub (`dive record`): the run's own end is recorded as its end, not a link loss.

The hub's socket closes when its run ends, which the session sees as any lost link. A run withdraws its
announcement (links/runs.py) before it closes its hub, so at that moment a run no longer announced as running
has ended: the recording says so (`run_ended`), and `dive log info` counts no link loss for it.
"""

from __future__ import annotations

from groundstation.links.runs import is_running
from groundstation.recording.recorder import Recorder
from groundstation.session.events import EventKind, LinkEvent, Received, Sent


class RunEndAware:
    """The recorder's session listener, with a lost hub link whose run has ended turned into that run's end."""

    def __init__(self, recorder: Recorder, run: str) -> None:
        self.recorder, self.run = recorder, run

    def on_received(self, received: Received) -> None:
        self.recorder.on_received(received)

    def on_unused(self, received: Received) -> None:
        self.recorder.on_unused(received)

    def on_sent(self, sent: Sent) -> None:
        self.recorder.on_sent(sent)

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.LINK_LOST and not is_running(self.run):
            event = LinkEvent(EventKind.RUN_ENDED, event.host_time_ns, f"dive run {self.run} ended and closed its hub",
                              {"run": self.run})
        self.recorder.on_event(event)
