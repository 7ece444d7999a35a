"""The main job behind `dive run`: connect, set parameters, start learning, record, stop after N episodes."""

from __future__ import annotations

import dataclasses
import os
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlsplit

from groundstation.errors import CommandError, CommandMayHaveRun, GroundStationError, LinkError, RecordingExistsError
from groundstation.links import make_link
from groundstation.links.hub_auth import new_token
from groundstation.links.runs import RunInfo, announce, new_run, refuse_if_held, withdraw
from groundstation.recording.recorder import Recorder, RecorderConfig
from groundstation.run.alarms import AlarmConfig, Alarms
from groundstation.run.history import History, HistoryConfig
from groundstation.run.hub import Hub
from groundstation.run.learner_restarts import LearnerRestarts
from groundstation.safe_output import one_line
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import EventKind, LinkEvent, Received, Sent, SessionListener
from groundstation.session.status_line import AgentStatus
from protocol import EndReason, Mode
from protocol import messages as m


def load_params_file(path: Path) -> dict[str, str]:
    """Parameters from a TOML file of `name = value` lines (groundstation/session/paramfile.py)."""
    from groundstation.session.paramfile import read_params

    return read_params(path)


DUMP_EACH_EPISODE_NAMES = ("dump_each_episode", "dump_each_ep")  # SPEC 1.1's name, and the agents' older one


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


ECHO = "> "  # how the run pane's echo of a command, marker or acknowledgement begins (cli/progress.py styles it)


class _Progress:
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


class _AgentWatch:
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


def _stop_agent(session: Session, depth: float | None) -> str:
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


@dataclass(frozen=True, slots=True)
class RunResult:
    paths: list[Path]
    status: RunStatus
    interrupted: bool
    still_missing: int
    lost: int = 0  # of still_missing: samples the agent's log no longer held (proved by its LOG_RANGE / HEARTBEAT)
    tools_dropped: int = 0  # tools the hub dropped for falling a whole queue behind (run/hub_outbox.py)


def session_info(url: str) -> dict[str, str]:
    info = {"url": url, "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    if url.startswith("sim://"):
        info.update({f"sim_{k}": v for k, v in parse_qsl(urlsplit(url).query)})
    return info


def _announce(info: RunInfo, recorder: Recorder) -> RunInfo:
    """Tell the machine's other dive commands where this run's hub is and which file it records (best effort)."""
    current = dataclasses.replace(info, recording=str(recorder.paths[-1]) if recorder.paths else "")
    try:
        announce(current)
    except OSError:
        pass  # a read-only runtime folder must not stop the run; tools then cannot attach
    return current


def run(config: RunConfig, on_progress: Callable[[RunStatus], None] | None = None,
        stop: threading.Event | None = None, listeners: Sequence[SessionListener] = (),
        ack: threading.Event | None = None) -> RunResult:
    """Run the main job; Ctrl-C (KeyboardInterrupt) or `stop` ends it early with a complete recording.

    `listeners` get the session's traffic too (the live Rerun view is one); `ack`, once set, acknowledges the
    alarms (the run pane's key), as a tool's `dive ack` does through the hub.
    """
    stop = stop or threading.Event()
    target = config.recorder.first_file
    if target is not None and target.exists():  # before connecting: the agent is not started for nothing
        raise RecordingExistsError(f"{one_line(target)} exists; a recording is never overwritten: give another name "
                                   "or a directory")
    if config.url is not None:
        refuse_if_held(config.url)  # another run holds this agent: one line, not two runs fighting over its link
    link = make_link(config.url)
    status = RunStatus()
    progress = _Progress(status)
    recorder = Recorder(config.recorder, session_info(link.url))
    history = History(config.history) if config.hub else None  # before the hub: nothing fanned out is missed
    session = Session(link, config.session, [recorder, progress, *([history] if history else []), *listeners])
    interrupted = False
    missing = 0
    hub: Hub | None = None
    announced: RunInfo | None = None
    backfilled = False
    try:
        session.connect()
        status.link_up = True
        if config.hub:
            token = new_token()
            hub = Hub(session, token)
            hub.history = history
            hub.start()
            session.add_listener(hub)
            announced = _announce(new_run(os.getpid(), hub.address, link.url, token), recorder)
            status.hub = f"hub://{announced.run}"
        alarms = Alarms(session, status.messages.append, config.alarms)
        session.add_listener(alarms)
        if hub is not None:
            hub.acknowledge = alarms.acknowledge
        if on_progress is not None:
            on_progress(status)  # connected: the display stops waiting for a (compiling) virtual agent
        values = dict(config.params)
        if config.dumps_each_episode:
            # The view's value and policy heatmaps fill from these; the user's own setting wins.
            name = next((n for n in DUMP_EACH_EPISODE_NAMES if n in session.params), None)
            if name is not None and not any(n in values for n in DUMP_EACH_EPISODE_NAMES):
                values[name] = "1"
        for name, value in values.items():
            session.set_param(name, value)
        recorder.set_parameters(session.params.values())
        for name in ("target_depth_m", "success_time_s"):  # the status line's target and success time
            if name in session.params:
                status.agent.param(name, session.params.get(name).value)
        watch = _AgentWatch(session, config.episodes, status, progress.restarts)
        watch.hub = hub
        watch.start()
        try:
            while not stop.is_set() and not (config.episodes and status.completed >= config.episodes):
                progress.changed.wait(0.2)
                progress.changed.clear()
                alarms.check()
                if ack is not None and ack.is_set():
                    ack.clear()
                    alarms.acknowledge("the run pane (key a)")
                status.alarm_flag = alarms.flag()
                if announced is not None and str(recorder.paths[-1] if recorder.paths else "") != \
                        announced.recording:
                    announced = _announce(announced, recorder)
                if on_progress is not None:
                    on_progress(status)
                if watch.finished() or recorder.failure is not None or session.failure is not None or \
                        session.listeners.failure is not None:
                    break
        except KeyboardInterrupt:
            interrupted = True
        # Stopped by the user, or by a recording that cannot go on (disk full, a listener that raised): the agent
        # stops too, as on Ctrl-C, rather than learn on with nobody recording (issue 25 M3).
        broken = recorder.failure is not None or session.listeners.failure is not None
        if (interrupted or stop.is_set() or broken) and session.failure is None:
            status.stopped = _stop_agent(session, status.agent.depth_m)
        elif config.episodes and status.completed >= config.episodes and session.failure is None:
            watch.stop_if_still_learning()
        missing = session.request_backfill(config.backfill_wait_s, final=True)
        backfilled = True
    except GroundStationError as e:
        # A run that ends on an error (CMD_START refused or unanswered, a parameter refused) still fetches what
        # the agent holds of what was lost before it closes: the recording is what matters.
        if session.agent_hello is not None and session.failure is None and not backfilled:
            missing = session.request_backfill(config.backfill_wait_s, final=True)
        if session.failure is not None and e is not session.failure:
            raise session.failure from e  # why the session stopped (the link taken), not the command it cut short
        raise
    finally:
        if announced is not None:
            withdraw(announced)
        if hub is not None:
            hub.close()
        session.close()
        recorder.close()
    if recorder.failure is not None:
        raise recorder.failure  # after the link was closed cleanly; what was written stays readable
    if session.failure is not None:
        raise session.failure  # another agent answered: nothing of it was recorded
    if session.listeners.failure is not None:
        raise session.listeners.failure  # the recorder (or the live view) raised: one line naming it
    if on_progress is not None:
        on_progress(status)
    return RunResult(list(recorder.paths), status, interrupted, missing, session.backfill_status()[0],
                     hub.dropped_slow if hub is not None else 0)
