"""The main job behind `dive run`: connect, set parameters, start learning, record, stop after N episodes.

Its parts: config.py (what it is told), status.py (what it shows and returns), progress.py (the episode count),
agent_watch.py (starting and following the agent), hub.py (other tools), alarms.py.
"""

from __future__ import annotations

import dataclasses
import os
import threading
import time
from collections.abc import Callable, Sequence
from urllib.parse import parse_qsl, urlsplit

from groundstation.errors import AgentBusy, GroundStationError, RecordingExistsError
from groundstation.links import make_link
from groundstation.links.hub_auth import new_token
from groundstation.links.runs import RunInfo, announce, new_run, refuse_if_held, withdraw
from groundstation.recording.recorder import Recorder
from groundstation.run.agent_watch import AgentWatch, stop_agent
from groundstation.run.alarms import Alarms
from groundstation.run.config import DUMP_EACH_EPISODE_NAMES as DUMP_EACH_EPISODE_NAMES
from groundstation.run.config import RunConfig as RunConfig
from groundstation.run.config import load_params_file as load_params_file
from groundstation.run.history import History
from groundstation.run.hub import Hub
from groundstation.run.progress import Progress
from groundstation.run.status import ECHO as ECHO
from groundstation.run.status import RunResult as RunResult
from groundstation.run.status import RunStatus as RunStatus
from groundstation.safe_output import one_line
from groundstation.session.agent_session import Session
from groundstation.session.events import SessionListener


def session_info(url: str) -> dict[str, str]:
    """What a recording's header says of its session: the link, when it started, a virtual agent's options."""
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


def _set_parameters(config: RunConfig, session: Session, recorder: Recorder, status: RunStatus) -> None:
    """The run's parameters set on the agent (dumps after every episode unless told otherwise), then recorded."""
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
    progress = Progress(status)
    recorder = Recorder(config.recorder, session_info(link.url))
    history = History(config.history) if config.hub else None  # before the hub: nothing fanned out is missed
    session = Session(link, config.session, [recorder, progress, *([history] if history else []), *listeners],
                      cancel=stop)  # a signal while a starting agent answers BUSY ends the wait
    interrupted = False
    commanded = False
    missing = 0
    hub: Hub | None = None
    announced: RunInfo | None = None
    backfilled = False
    try:
        if config.hub:
            # Announced while it connects (a virtual agent compiles for minutes): `dive record` and `dive status`
            # started now find the run and wait or say so, instead of "no dive run is running".
            token = new_token()
            announced = _announce(new_run(os.getpid(), "", link.url, token, state="connecting"), recorder)
        session.connect()
        status.link_up = True
        if announced is not None:
            hub = Hub(session, announced.token)
            hub.history = history
            hub.start()
            session.add_listener(hub)
            announced = _announce(dataclasses.replace(announced, hub=hub.address, state="running"), recorder)
            status.hub = f"hub://{announced.run}"
        alarms = Alarms(session, status.messages.append, config.alarms)
        session.add_listener(alarms)
        if hub is not None:
            hub.acknowledge = alarms.acknowledge
        if on_progress is not None:
            on_progress(status)  # connected: the display stops waiting for a (compiling) virtual agent
        _set_parameters(config, session, recorder, status)
        watch = AgentWatch(session, config.episodes, status, progress.restarts)
        watch.hub = hub
        commanded = True  # from here the agent may be learning: an interrupt must stop it
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
                if announced is not None and (announced.alarm != status.alarm_flag or
                                              str(recorder.paths[-1] if recorder.paths else "") != announced.recording):
                    announced = _announce(dataclasses.replace(announced, alarm=status.alarm_flag), recorder)
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
            status.stopped = stop_agent(session, status.agent.depth_m)
        elif config.episodes and status.completed >= config.episodes and session.failure is None:
            watch.stop_if_still_learning()
        missing = session.request_backfill(config.backfill_wait_s, final=True)
        backfilled = True
    except KeyboardInterrupt:
        # Ctrl-C before the loop (a starting agent's BUSY wait, the parameters being set) or after it: a stop like
        # any other, the file named and exit 130; the agent stopped if the run had set it going.
        interrupted = True
        if not status.stopped:
            status.stopped = stop_agent(session, status.agent.depth_m) if commanded and session.failure is None \
                else "nothing to stop: the run had not set the agent going"
    except AgentBusy as e:
        if not stop.is_set():
            raise
        # Stopped by a signal while the agent was still starting: a stop like any other (the file named, exit 130),
        # with nothing of the agent's to stop yet.
        interrupted = True
        status.stopped = f"nothing to stop: the agent was still starting ({one_line(e.reason)})"
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
    return RunResult(list(recorder.paths), status, interrupted, missing, session.backfill_status()[0], announced,
                     hub.dropped_slow if hub is not None else 0)
