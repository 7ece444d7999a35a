"""`--foxglove [PORT]`: a Foxglove WebSocket server with the agent live, its parameters and the operator's controls.

It answers the run's owner only (issue 38 N1): the operator's port is a door of ours (gate.py) that lets through the
owner's own processes (the kernel's socket table; a secret in the URL where the kernel cannot tell), and the SDK's
server behind it on an ephemeral loopback port gives channel data, parameters and services only to clients that
came through the door (their first frame, added by the door, advertises `owner_topic`). So a keyed run never signs
for whoever connects. The session its parameters and services use is a tool's like `dive view`'s: attached to the
run's hub (hub://RUN), so a surface or a pause from Foxglove is the operator's, which the run does not undo
(run/hub.py). On `dive run` the channels are published from the run's own session, off its reader thread
(`listener`: session/handoff.py).
"""

from __future__ import annotations

import contextlib
import errno
import logging
import queue
import secrets
import threading
import time
from collections.abc import Callable

import foxglove
from foxglove.websocket import Capability, ChannelView, Client, ClientChannel, ServerListener

from groundstation.errors import GroundStationError
from groundstation.links import make_link
from groundstation.links.peer import table_readable
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import SessionListener
from groundstation.session.handoff import Handoff
from groundstation.view.errors import ViewError
from groundstation.view.foxglove.channels import FoxgloveChannels, MarkerWatch
from groundstation.view.foxglove.gate import FoxgloveGate
from groundstation.view.foxglove.history import CLIENT_BACKLOG
from groundstation.view.foxglove.params import ParameterBridge
from groundstation.view.foxglove.services import Controls
from groundstation.view.options import FOXGLOVE_DEFAULT_PORT
from protocol import messages as m

HOST = "127.0.0.1"
DEFAULT_PORT = FOXGLOVE_DEFAULT_PORT
_STATUS_ID = "dive"
ATTACH_WAIT_S = 5.0  # a call while the server attaches waits this long for the agent before it is refused
OWNERS_REMEMBERED = 4096  # client ids that came through the door (ids are never reused: the oldest are forgotten)
REPLAY_SPACING_S = 1.0  # a client's topic is sent its history at most this often (a flapping subscription)
REPLAY_MESSAGES_PER_S = 20_000  # history messages sent per second, all clients together (10 000 SAMPLEs: 0.5 s)
HANDOFF_FRAMES = 65_536  # frames waiting for the publisher thread before the newest are dropped (and counted)


class FoxglovePortError(ViewError):
    """The port cannot be served on (in use, or privileged): the CLI says so in one line, exit 2."""


class _Listener(ServerListener):
    """The server's callbacks: a client is the owner's once the door's advertisement came first on its connection;
    history to a new subscriber, parameters through the bridge, for the owner's clients only; the rest are
    ServerListener's (which do nothing)."""

    def __init__(self, live: FoxgloveLive) -> None:
        self._live = live

    def on_client_advertise(self, client: Client, channel: ClientChannel) -> None:
        if secrets.compare_digest(channel.topic, self._live.owner_topic):
            self._live.owners[client.id] = None
            while len(self._live.owners) > OWNERS_REMEMBERED:
                self._live.owners.pop(next(iter(self._live.owners)))

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        # the SDK gives each WebSocket client a sink of its own, whose id is the client's: the history to it alone,
        # sent from a thread of ours, as this callback runs inside the server (which the session's thread may be
        # waiting for while it advertises a new channel)
        if self._live.is_owner(client.id):
            self._live.subscriptions.put((channel.topic, client.id, True))

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self._live.subscriptions.put((channel.topic, client.id, False))

    def on_get_parameters(self, client: Client, param_names: list[str],
                          request_id: str | None = None) -> list[foxglove.Parameter]:
        return self._live.parameters.get(param_names) if self._live.is_owner(client.id) else []

    def on_set_parameters(self, client: Client, parameters: list[foxglove.Parameter],
                          request_id: str | None = None) -> list[foxglove.Parameter]:
        return self._live.parameters.set(parameters) if self._live.is_owner(client.id) else []


class FoxgloveLive:
    """The server (bound at once: a port in use fails before anything else starts) and, once attached, the
    session whose frames it publishes and through which its parameters and services reach the agent."""

    def __init__(self, port: int, name: str = "dive") -> None:
        self.context = foxglove.Context()
        self.session: Session | None = None
        self._attached = threading.Event()
        self.failures: list[str] = []  # what went wrong after the start, for the run's terminal (attach_in_background)
        self.channels = FoxgloveChannels(self.context, self._parameter_changed, self._failed)
        self.markers = MarkerWatch()
        self.parameters = ParameterBridge(self.attached_session, self.warn)
        self.controls = Controls(self.attached_session, self.markers, self.warn, self.is_owner)
        self.owner_topic = f"/dive/owner/{secrets.token_hex(16)}"  # known to this process and its door only
        self.owners: dict[int, None] = {}  # client ids that came through the door, oldest first
        self.fingerprint = secrets.token_hex(3)  # in the server's name and the printed line: an impostor lacks it
        # (topic, sink id, subscribed or not), in the order the server saw them; None: the end
        self.subscriptions: queue.SimpleQueue[tuple[str, int, bool] | None] = queue.SimpleQueue()
        # the SDK logs a line per client that goes away untidily (hundreds in a flood) onto the run's terminal;
        # every client is the door's now, which counts what matters (gate.GateCounts)
        foxglove.set_log_level(logging.CRITICAL)
        try:
            self.gate = FoxgloveGate(HOST, port, self.owner_topic)  # first: a port in use fails before anything
        except OSError as e:
            why = "is in use by another process" if e.errno == errno.EADDRINUSE else f"cannot be served on ({e})"
            raise FoxglovePortError(f"port {port} {why}: choose another with --foxglove PORT") from None
        try:
            self.server = foxglove.start_server(
                name=f"{name} #{self.fingerprint}", host=HOST, port=0, context=self.context,
                server_listener=_Listener(self), supported_encodings=["json"],
                capabilities=[Capability.Parameters, Capability.Services, Capability.ClientPublish],
                services=self.controls.services(), message_backlog_size=CLIENT_BACKLOG)
        except RuntimeError as e:  # the SDK's FoxgloveError: "Failed to bind port: ..."
            self.gate.close()
            raise FoxglovePortError(f"the Foxglove server cannot start ({e})") from None
        self.gate.start(self.server.port)
        self.port = self.gate.port
        # the run's session hands its frames over and goes on: encoding and sending are the publisher thread's
        self.listener = Handoff(self.channels, HANDOFF_FRAMES, "dive-foxglove-publish")
        self._closed = threading.Event()
        threading.Thread(target=self._subscriptions, name="dive-foxglove-subscriptions", daemon=True).start()
        self._say: Callable[[str], None] | None = None

    @property
    def address(self) -> str:
        """The URL the owner opens: the door's port (with its secret path where the kernel cannot name a peer)."""
        return f"ws://{HOST}:{self.port}" + ("" if table_readable() else f"/{self.gate.token}")

    def is_owner(self, client_id: int) -> bool:
        return client_id in self.owners

    def refusals(self) -> str:
        """What the door refused or dropped and the publisher could not keep up with ("" if nothing), counted."""
        counts = self.gate.counts
        parts = [f"{n} {what}" for n, what in (
            (counts.refused_user, "connections of another user refused"),
            (counts.refused_full, "refused as too many"),
            (counts.dropped_slow, "clients dropped for not reading"),
            (self.listener.dropped, "frames not published (the publisher fell behind)"),
            (self.channels.held_back_dropped, "live messages dropped while a history was sent")) if n]
        return ", ".join(parts)

    def attach(self, url: str, key: bytes | None, publish: bool = True) -> Session:
        """Connect the session the parameters and services use to `url` (hub://RUN for a run's hub); raises as a
        tool's connect does (one line). `publish`: what it receives goes to the channels (`dive view`); a run
        publishes from its own session instead (self.channels is one of its listeners). Through a hub the run
        backfills for every tool: no LOG_REQUESTs of our own."""
        listeners: list[SessionListener] = [self.markers, *([self.listener] if publish else [])]
        # named "foxglove": a run's pane says a command came from it (run/echo.py)
        session = Session(make_link(url), SessionConfig(key=key, backfill=not url.startswith("hub://"),
                                                        name="foxglove"), listeners=listeners)
        session.connect()
        if self._closed.is_set():
            session.close()
            raise ViewError("the Foxglove server was closed while it attached")
        self.session = session
        self._attached.set()
        self.server.remove_status([_STATUS_ID])
        return session

    def attach_in_background(self, url: str, key: bytes | None, say: Callable[[str], None]) -> threading.Thread:
        """attach(publish=False) in a thread (a run must not wait for it); `say(line)` tells the run's terminal
        why it failed, and later why publishing stopped, if it does."""
        self._say = say

        def attach() -> None:
            try:
                self.attach(url, key, publish=False)
            except GroundStationError as e:
                say(f"Foxglove could not attach to {url}: {e}")
                self.warn(f"not attached to the agent: {e}")

        thread = threading.Thread(target=attach, name="dive-foxglove-attach", daemon=True)
        thread.start()
        return thread

    def attached_session(self) -> Session | None:
        """The session, waiting up to ATTACH_WAIT_S for it: a panel asks for the parameters as soon as it connects,
        which can be while a run's agent is still starting."""
        self._attached.wait(ATTACH_WAIT_S)
        return self.session

    def warn(self, line: str) -> None:
        """A line in Foxglove's problems list (replacing the last one)."""
        if not self._closed.is_set():
            self.server.publish_status(line, foxglove.StatusLevel.Warning, _STATUS_ID)

    def _subscriptions(self) -> None:
        """Subscriptions, coalesced: an unsubscribe is done at once (it only stops sending), a subscribe is done
        once for all that came before it, and a client's topic is sent its history at most once every
        REPLAY_SPACING_S: a client flapping a subscription gets one history in flight and the next one later,
        not one per flap queued without end (issue 38 N3)."""
        pending: set[tuple[str, int]] = set()  # subscribed, history not sent yet
        replayed_s: dict[tuple[str, int], float] = {}  # when each (topic, sink) was last sent its history
        while True:
            waits = [replayed_s.get(key, 0.0) + REPLAY_SPACING_S for key in pending]
            changes: list[tuple[str, int, bool] | None] = []
            with contextlib.suppress(queue.Empty):
                changes.append(self.subscriptions.get(
                    timeout=max(0.0, min(waits) - time.monotonic()) if waits else None))
                while True:
                    changes.append(self.subscriptions.get_nowait())
            for change in changes:
                if change is None:
                    return
                topic, sink_id, subscribed = change
                if subscribed:
                    pending.add((topic, sink_id))
                else:
                    pending.discard((topic, sink_id))
                    self.channels.unsubscribed(topic, sink_id)
            now_s = time.monotonic()
            for key in sorted(pending):
                if now_s >= replayed_s.get(key, 0.0) + REPLAY_SPACING_S:
                    pending.discard(key)
                    self.channels.replayed = 0
                    self.channels.subscribed(*key)
                    sent = self.channels.replayed
                    # a budget for all clients together: each history's sending costs the process's CPU (and so,
                    # on a loaded machine, the session's reader thread) however many clients come and go
                    if self._closed.wait(sent / REPLAY_MESSAGES_PER_S):
                        return
                    replayed_s[key] = now_s = time.monotonic()
            for key in [key for key, when_s in replayed_s.items() if now_s - when_s > REPLAY_SPACING_S]:
                del replayed_s[key]

    def _parameter_changed(self, value: m.ParamValue) -> None:
        """A PARAM_VALUE is not pushed: the SDK sends pushed values to every client that subscribed to parameter
        updates, owner or not (a connection straight to the inner port can subscribe). The Parameters panel shows
        what its get and set answer (the owner's only)."""

    def _failed(self, line: str) -> None:
        self.warn(line)
        if self._say is not None:
            self._say(line)

    def close(self) -> None:
        self._closed.set()
        self.subscriptions.put(None)
        self.listener.close()
        session, self.session = self.session, None
        if session is not None:
            session.close()
        self.gate.close()
        self.server.stop()
