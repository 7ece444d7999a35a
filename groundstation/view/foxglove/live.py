"""`--foxglove [PORT]`: a Foxglove WebSocket server with the agent live, its parameters and the operator's controls.

It binds 127.0.0.1 only and answers every local user of this machine: Foxglove's protocol has no login, so whoever
can open ws://127.0.0.1:PORT here watches the agent, sets its parameters and commands it (signed with the run's key
on a keyed run). The session its parameters and services use is a tool's like `dive view`'s: attached to the run's
hub (hub://RUN), so a surface or a pause from Foxglove is the operator's, which the run does not undo (run/hub.py).
On `dive run` the channels are published from the run's own session (FoxgloveChannels is one of its listeners).
"""

from __future__ import annotations

import queue
import threading
from collections.abc import Callable

import foxglove
from foxglove.websocket import Capability, ChannelView, Client, ServerListener

from groundstation.errors import GroundStationError
from groundstation.links import make_link
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import SessionListener
from groundstation.session.params import Parameter
from groundstation.view.errors import ViewError
from groundstation.view.foxglove.channels import FoxgloveChannels, MarkerWatch
from groundstation.view.foxglove.history import CLIENT_BACKLOG
from groundstation.view.foxglove.params import ParameterBridge, to_foxglove
from groundstation.view.foxglove.services import Controls
from groundstation.view.options import FOXGLOVE_DEFAULT_PORT
from protocol import messages as m

HOST = "127.0.0.1"
DEFAULT_PORT = FOXGLOVE_DEFAULT_PORT
_STATUS_ID = "dive"
ATTACH_WAIT_S = 5.0  # a call while the server attaches waits this long for the agent before it is refused


class FoxglovePortError(ViewError):
    """The port cannot be served on (in use, or privileged): the CLI says so in one line, exit 2."""


class _Listener(ServerListener):
    """The server's callbacks: history to a new subscriber, parameters through the bridge; the rest are
    ServerListener's (which do nothing)."""

    def __init__(self, live: FoxgloveLive) -> None:
        self._live = live

    def on_subscribe(self, client: Client, channel: ChannelView) -> None:
        # the SDK gives each WebSocket client a sink of its own, whose id is the client's: the history to it alone,
        # sent from a thread of ours, as this callback runs inside the server (which the session's thread may be
        # waiting for while it advertises a new channel)
        self._live.subscriptions.put((channel.topic, client.id, True))

    def on_unsubscribe(self, client: Client, channel: ChannelView) -> None:
        self._live.subscriptions.put((channel.topic, client.id, False))

    def on_get_parameters(self, client: Client, param_names: list[str],
                          request_id: str | None = None) -> list[foxglove.Parameter]:
        return self._live.parameters.get(param_names)

    def on_set_parameters(self, client: Client, parameters: list[foxglove.Parameter],
                          request_id: str | None = None) -> list[foxglove.Parameter]:
        return self._live.parameters.set(parameters)


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
        self.controls = Controls(self.attached_session, self.markers, self.warn)
        # (topic, sink id, subscribed or not), in the order the server saw them; None: the end
        self.subscriptions: queue.SimpleQueue[tuple[str, int, bool] | None] = queue.SimpleQueue()
        try:
            self.server = foxglove.start_server(
                name=name, host=HOST, port=port, context=self.context, server_listener=_Listener(self),
                capabilities=[Capability.Parameters, Capability.Services], supported_encodings=["json"],
                services=self.controls.services(), message_backlog_size=CLIENT_BACKLOG)
        except RuntimeError as e:  # the SDK's FoxgloveError: "Failed to bind port: Address already in use ..."
            why = "is in use by another process" if "in use" in str(e) else f"cannot be served on ({e})"
            raise FoxglovePortError(f"port {port} {why}: choose another with --foxglove PORT") from None
        self.port = self.server.port
        threading.Thread(target=self._subscriptions, name="dive-foxglove-subscriptions", daemon=True).start()
        self._closed = threading.Event()
        self._say: Callable[[str], None] | None = None

    @property
    def address(self) -> str:
        return f"ws://{HOST}:{self.port}"

    def attach(self, url: str, key: bytes | None, publish: bool = True) -> Session:
        """Connect the session the parameters and services use to `url` (hub://RUN for a run's hub); raises as a
        tool's connect does (one line). `publish`: what it receives goes to the channels (`dive view`); a run
        publishes from its own session instead (self.channels is one of its listeners). Through a hub the run
        backfills for every tool: no LOG_REQUESTs of our own."""
        listeners: list[SessionListener] = [self.markers, *([self.channels] if publish else [])]
        # named "foxglove": a run's pane says a command came from it (run/echo.py)
        session = Session(make_link(url), SessionConfig(key=key, backfill=not url.startswith("hub://"),
                                                        name="foxglove"), listeners=listeners)
        session.connect()
        if self._closed.is_set():
            session.close()
            raise ViewError("the Foxglove server was closed while it attached")
        self.session = session
        self._attached.set()
        self.server.publish_parameter_values([to_foxglove(p) for p in session.params])
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
        while (change := self.subscriptions.get()) is not None:
            topic, sink_id, subscribed = change
            if subscribed:
                self.channels.subscribed(topic, sink_id)
            else:
                self.channels.unsubscribed(topic, sink_id)

    def _parameter_changed(self, value: m.ParamValue) -> None:
        """Any PARAM_VALUE (this server's set, another tool's, the run's) updates the panels that show it."""
        if self._attached.is_set():  # attach() publishes the whole table once
            self.server.publish_parameter_values([to_foxglove(Parameter.from_message(value))])

    def _failed(self, line: str) -> None:
        self.warn(line)
        if self._say is not None:
            self._say(line)

    def close(self) -> None:
        self._closed.set()
        self.subscriptions.put(None)
        session, self.session = self.session, None
        if session is not None:
            session.close()
        self.server.stop()
