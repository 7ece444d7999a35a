"""Starts learning and follows the agent's mode, so the run neither hangs nor stalls; stops it when the run ends."""

from __future__ import annotations

import time

from groundstation.errors import CommandError, CommandMayHaveRun, LinkError
from groundstation.run.hub import Hub
from groundstation.run.learner_restarts import LearnerRestarts
from groundstation.run.status import RunStatus
from groundstation.safe_output import one_line
from groundstation.session.agent_session import Session
from protocol import Mode
from protocol import messages as m


class AgentWatch:
    """Starts learning and follows the agent's mode from its heartbeats, so the run neither hangs nor stalls.

    EPISODE_END frames are what the run counts, but one can be lost on the link; the agent's own episode counter
    (HEARTBEAT.episode) and its return to IDLE say the episodes are done all the same (the final backfill then
    fetches the lost frames). An agent that surfaced for another reason (link loss, maximum dive time) before
    the episodes were done is started again with the episodes left.
    """

    MAX_RESTARTS = 10
    SURFACING_WAIT_S = 60.0
    FIRST_HEARTBEAT_WAIT_S = 2.0  # heartbeats come at 1 Hz of agent time
    START_WAIT_S = 60.0
    BACKFILL_AT_SURFACE_S = 3.0  # wait after the last backfilled sample before a restart (at most 4x in all)
    BATTERY_MARGIN_V = 0.005  # HEARTBEAT.battery_mv is whole millivolts: 3.399 V reads as 3.40 at 3.40 V

    def __init__(self, session: Session, episodes: int, status: RunStatus, restarts: LearnerRestarts) -> None:
        self.session, self.episodes, self.status = session, episodes, status
        self.chapters = restarts  # the run's count across learner restarts
        self.first_episode = 0
        self.left_idle = False
        self.restarts = 0
        self._episode_before = 0  # the agent's episode counter when the run last sent CMD_START
        self.hub: Hub | None = None  # a tool's CMD_SURFACE / STOP / HOVER / PAUSE through it: no restart
        self._operator: str | None = None  # the take-over last said

    def start(self) -> None:
        beat = self._wait_unless_surfacing()
        self.first_episode = self._episode_before = beat.episode if beat is not None else 0
        self.chapters.started_at(self.first_episode)
        if beat is not None and beat.mode in (Mode.LEARNING, Mode.RECOVERING):
            self.status.messages.append(f"the agent is already learning (episode {beat.episode}): recording it")
            self.left_idle = True
            return
        # retried with the same seq (across reconnects) for up to START_WAIT_S: on a link that drops every second
        # four tries are not enough, and the agent's ACK memory makes a repeat harmless
        try:
            self.session.command(m.StartLearning(max_episodes=self.episodes), timeout_s=self.START_WAIT_S)
        except CommandMayHaveRun as e:
            # A retry across a session start (our HELLO repeated on a lossy link empties the agent's ACK memory) ran
            # again and was refused because the first try had started it (SPEC.md s. 5): learning is what we asked.
            if e.mode not in (Mode.LEARNING.name, Mode.RECOVERING.name):
                raise
            self.status.messages.append(f"CMD_START's first try ran (its retry crossed a reconnect): the agent is "
                                        f"{e.mode}")

    def finished(self) -> bool:
        self.follow_operator()
        beat = self.session.last_heartbeat
        if beat is None:
            return False
        if beat.mode != Mode.IDLE:
            self.left_idle = True
            return False
        if not self.left_idle and beat.episode <= self._episode_before:
            # the heartbeat from before CMD_START; an IDLE one that counts more episodes is from after it (an agent
            # that surfaced at once, between two heartbeats)
            return False
        done = self.chapters.run_episodes(beat.episode)  # the run's, across learner restarts
        if self.episodes and done >= self.episodes:
            return True
        if self._operator is not None:
            return False
        if self.restarts >= self.MAX_RESTARTS:
            self.status.messages.append(f"the agent surfaced {self.restarts} times; stopping")
            return True
        flat = self._flat_battery_v(beat)
        if flat is not None:
            # It would surface again at once (SPEC s. 6): restarting only adds aborted episodes.
            self.status.messages.append(f"the agent's battery is flat ({flat:.2f} V, it surfaces below low_batt_v): "
                                        "stopping; recharge it (a virtual agent starts full)")
            return True
        self.restarts += 1
        self.left_idle = False
        self._episode_before = beat.episode
        left = self.episodes - done if self.episodes else 0
        self.status.messages.append(f"the agent surfaced after episode {beat.episode}; starting it again")
        # At the surface the radio works: fetch what was lost while it was deep before it dives again, or the
        # on-board log may turn over before the next window (issue 13 item 4).
        self.session.request_backfill(timeout_s=self.BACKFILL_AT_SURFACE_S, limit_s=4 * self.BACKFILL_AT_SURFACE_S)
        try:
            self.session.command(m.StartLearning(max_episodes=left))
        except (CommandError, LinkError) as e:
            self.left_idle = True  # try again on the next look
            self.status.messages.append(f"restart refused: {e}")
        return False

    def _flat_battery_v(self, beat: m.Heartbeat) -> float | None:
        """The agent's battery voltage if it is at or below the voltage it surfaces at (low_batt_v), else None."""
        if not beat.battery_mv or "low_batt_v" not in self.session.params:
            return None
        volts = beat.battery_mv / 1000
        return volts if volts <= self.session.params.get("low_batt_v").value + self.BATTERY_MARGIN_V else None

    def follow_operator(self) -> None:
        """One line when an operator takes the agent from the run through the hub, and when they hand it back."""
        now = self.hub.taken_over if self.hub is not None else None
        if now == self._operator:
            return
        self._operator = now
        if now is None:
            self.left_idle = False  # a heartbeat from before the operator's CMD_START is not the end of it
            line = "the operator handed the agent back (CMD_START): the run goes on with its episodes"
        elif now == "CMD_PAUSE":
            line = ("the operator paused learning (CMD_PAUSE from another tool): the agent holds its depth; "
                    "dive resume continues")
        else:
            line = (f"the operator took over ({now} from another tool): the run will not start the agent again, "
                    "still recording; hand it back with: dive start")
        self.status.messages.append(line)

    def stop_if_still_learning(self) -> None:
        """The run's episodes are done but the agent learns on (an operator's CMD_START had no budget): surface it."""
        beat = self.session.last_heartbeat
        if beat is None or beat.mode not in (Mode.LEARNING, Mode.RECOVERING, Mode.PAUSED):
            return
        if self.hub is not None and self.hub.taken_over is not None:
            return  # the operator's
        try:
            self.session.command(m.Stop())
        except (CommandError, LinkError):
            pass  # the agent's own budget or link loss surfaces it

    def _wait_unless_surfacing(self) -> m.Heartbeat | None:
        """The agent's latest heartbeat (waiting up to 2 s for one), once it is not surfacing any more."""
        first_deadline = time.monotonic() + self.FIRST_HEARTBEAT_WAIT_S
        while self.session.last_heartbeat is None and time.monotonic() < first_deadline:
            time.sleep(0.05)
        deadline = time.monotonic() + self.SURFACING_WAIT_S
        beat = self.session.last_heartbeat
        while beat is not None and beat.mode == Mode.SURFACING and time.monotonic() < deadline:
            time.sleep(0.1)
            beat = self.session.last_heartbeat
        return beat


def stop_agent(session: Session, depth: float | None) -> str:
    """CMD_STOP to an agent left learning, hovering or paused; the line saying what it was doing and what came of it
    ("the agent was RECOVERING at 0.68 m: CMD_STOP accepted, it surfaces")."""
    beat = session.last_heartbeat
    mode = Mode(beat.mode) if beat is not None and beat.mode in Mode._value2member_map_ else None
    was = f"the agent was {mode.name if mode is not None else 'in an unknown mode'}" + \
        (f" at {depth:.2f} m" if depth is not None else "")
    try:
        session.command(m.Stop())
    except (CommandError, LinkError) as e:
        # the recording is what matters now; an agent surfaces on link loss when surface_on_link_loss is set
        return f"{was}: CMD_STOP not answered ({one_line(str(e))}); check it with dive status"
    if mode in (Mode.IDLE, Mode.SURFACING):
        return f"{was}: CMD_STOP accepted, nothing to stop"
    return f"{was}: CMD_STOP accepted, it surfaces (SURFACING)"
