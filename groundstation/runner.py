"""The main job behind `dive run`: connect, set parameters, start learning, record, stop after N episodes."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl, urlsplit

from groundstation.errors import CommandError, GroundStationError, LinkError, ParameterError, RecordingExistsError
from groundstation.events import EventKind, LinkEvent, Received, Sent, SessionListener
from groundstation.links import make_link
from groundstation.params import cache_dir
from groundstation.recorder import Recorder, RecorderConfig
from groundstation.safe_output import one_line
from groundstation.session import Session, SessionConfig
from protocol import EndReason, Mode
from protocol import messages as m


def marker_file() -> Path:
    """Where `dive mark` appends and a running `dive run` looks (one JSON line per marker)."""
    return cache_dir() / "markers.jsonl"


def add_marker(text: str) -> Path:
    path = marker_file()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("a") as f:
            f.write(json.dumps({"text": text, "host_time_ns": time.time_ns()}) + "\n")
    except OSError as e:
        raise GroundStationError(f"cannot write the marker file {path}: {e.strerror or e}") from e
    return path


MARKER_READ_BYTES = 1 << 20  # read at most this much of the marker file per look


class MarkerWatcher:
    """Reads markers appended to the marker file since this run started."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._offset = path.stat().st_size if path.exists() else 0

    def poll(self) -> list[str]:
        """Whole new lines only (one being written is read next time); a line that is not a JSON object with a
        text, or not UTF-8, is skipped: the file is anyone's to write, and must never stop a running session."""
        try:
            with self.path.open("rb") as f:
                f.seek(self._offset)
                data = f.read(MARKER_READ_BYTES)
        except OSError:
            return []
        complete = data[: data.rfind(b"\n") + 1] if len(data) < MARKER_READ_BYTES else data
        self._offset += len(complete)
        texts = []
        for line in complete.splitlines():
            try:
                body = json.loads(line.decode("utf-8", errors="replace"))
            except ValueError:
                continue
            if isinstance(body, dict) and isinstance(body.get("text"), str):
                texts.append(body["text"])
        return texts


def load_params_file(path: Path) -> dict[str, str]:
    """Parameters from a JSON object or `name = value` lines (# comments allowed)."""
    try:
        text = path.read_text()
    except OSError as e:
        raise ParameterError(f"cannot read parameter file {path}: {e.strerror or e}") from e
    if text.lstrip().startswith("{"):
        try:
            return {str(k): str(v).lower() if isinstance(v, bool) else str(v) for k, v in json.loads(text).items()}
        except ValueError as e:
            raise ParameterError(f"{path}: not valid JSON ({e})") from e
    values = {}
    for number, line in enumerate(text.splitlines(), 1):
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        if "=" not in line:
            raise ParameterError(f"{path}:{number}: expected `name = value`")
        name, value = (part.strip() for part in line.split("=", 1))
        values[name] = value
    return values


@dataclass(frozen=True, slots=True)
class RunConfig:
    url: str | None = None
    episodes: int = 0  # 0 = until stopped
    params: dict[str, str] = field(default_factory=dict)
    recorder: RecorderConfig = field(default_factory=RecorderConfig)
    session: SessionConfig = field(default_factory=SessionConfig)
    backfill_wait_s: float = 10.0


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


class _Progress:
    """A session listener that counts episodes and keeps the latest link statistics."""

    def __init__(self, status: RunStatus) -> None:
        self.status = status
        self.changed = threading.Event()
        self._episodes: set[int] = set()

    def on_received(self, received: Received) -> None:
        msg = received.message
        if isinstance(msg, m.Sample):
            self.status.samples += 1
        elif isinstance(msg, m.EpisodeEnd) and msg.episode not in self._episodes:
            self._episodes.add(msg.episode)
            s = self.status
            s.episodes += 1
            s.successes += msg.reason == EndReason.SUCCESS
            s.failures += msg.reason == EndReason.FAILURE
            s.last_duration_s = msg.duration_s
            s.last_reason = EndReason(msg.reason).name.lower() if msg.reason in (1, 2, 3) else str(msg.reason)
            self.changed.set()

    def on_sent(self, sent: Sent) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.STATS:
            self.status.link = event.data.get("link", {})
        elif event.kind in (EventKind.LINK_LOST, EventKind.LINK_RESTORED, EventKind.RESYNCED, EventKind.ERROR):
            self.status.messages.append(f"{event.kind}: {event.detail}")
        self.status.link_up = event.kind != EventKind.LINK_LOST if event.kind != EventKind.STATS else \
            self.status.link_up
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

    def __init__(self, session: Session, episodes: int, status: RunStatus) -> None:
        self.session, self.episodes, self.status = session, episodes, status
        self.first_episode = 0
        self.left_idle = False
        self.restarts = 0

    def start(self) -> None:
        beat = self._wait_unless_surfacing()
        self.first_episode = beat.episode if beat is not None else 0
        if beat is not None and beat.mode in (Mode.LEARNING, Mode.RECOVERING):
            self.status.messages.append(f"the agent is already learning (episode {beat.episode}): recording it")
            self.left_idle = True
            return
        # retried with the same seq (across reconnects) for up to START_WAIT_S: on a link that drops every second
        # four tries are not enough, and the agent's ACK memory makes a repeat harmless
        self.session.command(m.StartLearning(max_episodes=self.episodes), timeout_s=self.START_WAIT_S)

    def finished(self) -> bool:
        beat = self.session.last_heartbeat
        if beat is None:
            return False
        if beat.mode != Mode.IDLE:
            self.left_idle = True
            return False
        if not self.left_idle:
            return False  # the heartbeat from before CMD_START
        done = beat.episode - self.first_episode
        if self.episodes and done >= self.episodes:
            return True
        if self.restarts >= self.MAX_RESTARTS:
            self.status.messages.append(f"the agent surfaced {self.restarts} times; stopping")
            return True
        self.restarts += 1
        self.left_idle = False
        left = self.episodes - done if self.episodes else 0
        self.status.messages.append(f"the agent surfaced after episode {beat.episode}; starting it again")
        try:
            self.session.command(m.StartLearning(max_episodes=left))
        except (CommandError, LinkError) as e:
            self.left_idle = True  # try again on the next look
            self.status.messages.append(f"restart refused: {e}")
        return False

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


@dataclass(frozen=True, slots=True)
class RunResult:
    paths: list[Path]
    status: RunStatus
    interrupted: bool
    still_missing: int
    lost: int = 0  # of still_missing: samples the agent's log no longer held (proved by its LOG_RANGE / HEARTBEAT)


def session_info(url: str) -> dict[str, str]:
    info = {"url": url, "started": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    if url.startswith("sim://"):
        info.update({f"sim_{k}": v for k, v in parse_qsl(urlsplit(url).query)})
    return info


def run(config: RunConfig, on_progress: Callable[[RunStatus], None] | None = None,
        stop: threading.Event | None = None, listeners: Sequence[SessionListener] = ()) -> RunResult:
    """Run the main job; Ctrl-C (KeyboardInterrupt) or `stop` ends it early with a complete recording.

    `listeners` get the session's traffic too (the live Rerun view is one).
    """
    stop = stop or threading.Event()
    target = config.recorder.path
    if target is not None and target.exists():  # before connecting: the agent is not started for nothing
        raise RecordingExistsError(f"{one_line(target)} exists; a recording is never overwritten: give another name "
                                   "or a directory")
    link = make_link(config.url)
    status = RunStatus()
    progress = _Progress(status)
    recorder = Recorder(config.recorder, session_info(link.url))
    session = Session(link, config.session, [recorder, progress, *listeners])
    markers = MarkerWatcher(marker_file())
    interrupted = False
    missing = 0
    backfilled = False
    try:
        session.connect()
        status.link_up = True
        for name, value in config.params.items():
            session.set_param(name, value)
        recorder.set_parameters(session.params.values())
        watch = _AgentWatch(session, config.episodes, status)
        watch.start()
        try:
            while not stop.is_set() and not (config.episodes and status.episodes >= config.episodes):
                progress.changed.wait(0.2)
                progress.changed.clear()
                for text in markers.poll():
                    session.mark(text)
                if on_progress is not None:
                    on_progress(status)
                if watch.finished() or recorder.failure is not None or session.failure is not None:
                    break
        except KeyboardInterrupt:
            interrupted = True
        if (interrupted or stop.is_set()) and session.failure is None:
            try:
                session.command(m.Stop())
            except (CommandError, LinkError):
                pass  # the recording is what matters now; the agent surfaces on link loss anyway
        missing = session.request_backfill(config.backfill_wait_s, final=True)
        backfilled = True
    except GroundStationError:
        # A run that ends on an error (CMD_START refused or unanswered, a parameter refused) still fetches what
        # the agent holds of what was lost before it closes: the recording is what matters.
        if session.agent_hello is not None and session.failure is None and not backfilled:
            missing = session.request_backfill(config.backfill_wait_s, final=True)
        raise
    finally:
        session.close()
        recorder.close()
    if recorder.failure is not None:
        raise recorder.failure  # after the link was closed cleanly; what was written stays readable
    if session.failure is not None:
        raise session.failure  # another agent answered: nothing of it was recorded
    if on_progress is not None:
        on_progress(status)
    return RunResult(list(recorder.paths), status, interrupted, missing, session.backfill_status()[0])
