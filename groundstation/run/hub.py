"""The hub: a running `dive run` shares its one session with the agent with local tools (as MAVProxy's outputs).

The agent has one TCP slot (so does the ESP8266 bridge); a second tool connecting to it would take the link
from the run. Instead the run's session re-serves the agent's frames on a loopback TCP port, in the agent's
own protocol, so `dive view`, `status`, `mark`, `surface`, ... attach with the same link code as to an agent:

- a connection first proves it holds the run's token (links/hub_auth.py); anything else is closed unanswered;
- every frame the session delivers is fanned out to every client, re-framed with the client's own seq
  (the REPLAYED flag kept), so a client's loss count is its own link's; TIMESYNC answers (the run's) are not;
- a client's HELLO is answered with the agent's HELLO, its HEARTBEATs are dropped (the run sends its own);
- a client's command is checked, sent to the agent by the session once, and its ACK sent back with the client's
  seq (run/hub_commands.py);
- a client's TIMESYNC request is answered by the hub from the run's clock model: no tool's TIMESYNC reaches the agent;
- a client's TEXT is a marker for the run's recording (`dive mark`), confirmed by a TEXT back; a ground-flagged
  TEXT `ack` acknowledges the run's alarms (`dive ack`, run/alarms.py), answered by a TEXT saying what was;
- the run's markers and alarms are fanned out too, each as a TEXT flagged as the ground's (links/hub_events.py): a
  `dive record` attached to the run records them, a `dive view` shows them, as the run's own recorder and view do.

Every tool has a writer thread and a bounded queue of its own (run/hub_outbox.py): the session's reader thread only
appends each frame to the queues, and never waits for a tool. A tool that falls a whole queue behind is dropped,
told why in a last ground TEXT its session stops on; the run counts it (dropped_slow, in the run's last lines).
"""

from __future__ import annotations

import contextlib
import selectors
import socket
import threading
import time
from collections.abc import Callable

from groundstation.links.hub_auth import FULL as HUB_FULL
from groundstation.links.hub_auth import HubAuthError, HubSide
from groundstation.links.hub_events import ACK_REQUEST, FANNED_OUT, GROUND_FLAG, ground_text, parse_ground_text
from groundstation.links.peer import peer_is_owner
from groundstation.run.history import History
from groundstation.run.hub_clients import FORWARDED, HANDSHAKE_S, MAX_CLIENTS, MAX_REJECTS, HubClient
from groundstation.run.hub_commands import CommandForwarder
from groundstation.run.hub_outbox import TOOL_QUEUE_FRAMES, ToolOutbox, frame_entry
from groundstation.run.marker import CONFIRMATION as MARKER_CONFIRMATION
from groundstation.safe_output import one_line
from groundstation.session.agent_session import Session
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import AckResult, FrameFlag, Message
from protocol import messages as m

_KEPT_FLAGS = int(FrameFlag.REPLAYED)  # of an agent frame; the rest (GROUND_FLAG too) cleared: no forged events
_U64_MAX = 2**64 - 1
_Client = HubClient


class Hub:
    """A session listener and a loopback TCP server; start() after the session is connected."""

    def __init__(self, session: Session, token: str, host: str = "127.0.0.1", port: int = 0,
                 tool_queue_frames: int = TOOL_QUEUE_FRAMES) -> None:
        self.session = session
        self.tool_queue_frames = tool_queue_frames  # how far behind a tool may fall before it is dropped
        self._token = token
        self._listener = socket.create_server((host, port))
        self._listener.setblocking(False)
        bound_host, bound_port = self._listener.getsockname()[:2]
        self.address = f"tcp://{bound_host}:{bound_port}"
        self._selector = selectors.DefaultSelector()
        self._selector.register(self._listener, selectors.EVENT_READ, None)
        self._wake_r, self._wake_w = socket.socketpair()
        self._wake_r.setblocking(False)
        self._wake_w.setblocking(False)
        self._selector.register(self._wake_r, selectors.EVENT_READ, None)
        self._lock = threading.Lock()
        self._clients: list[_Client] = []
        # The attached tools that said HELLO, those every frame goes to: a tuple replaced whole under the lock, read
        # without it by the session's reader thread (which so takes no lock the hub's thread holds)
        self._fanout: tuple[_Client, ...] = ()
        self._closing: list[_Client] = []  # dropped, their writer thread still ending: the socket closed after it
        self.commands = CommandForwarder(session, self._lock, lambda client: client in self._clients)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="dive-hub", daemon=True)
        self.markers = 0
        self.clients_served = 0
        self.refused_users = 0  # connections from another user's processes, closed at accept
        self.dropped_slow = 0  # tools dropped for falling a whole queue behind (run/hub_outbox.py)
        self.history: History | None = None  # what a tool's LOG_REQUEST is answered from (set by the run)
        # A tool's `dive ack`: the run's alarms acknowledged by that tool; the line saying what was (set by the run)
        self.acknowledge: Callable[[str], str] | None = None

    # ------------------------------------------------------------------ life cycle
    def start(self) -> Hub:
        self._thread.start()
        return self

    def close(self) -> None:
        self._stop.set()
        self._wake()
        if self._thread.is_alive():
            self._thread.join(5.0)
        with self._lock:
            clients, self._clients, self._fanout = self._clients + self._closing, [], ()
            self._closing = []
        for client in clients:
            self._shut(client)
        for client in clients:
            if client.outbox is not None:
                client.outbox.close(1.0)
            with contextlib.suppress(OSError):
                client.sock.close()
        for sock in (self._listener, self._wake_r, self._wake_w):
            with contextlib.suppress(OSError):
                sock.close()
        self._selector.close()

    @property
    def taken_over(self) -> str | None:
        """The tool's command that took the agent out of learning, None if none or a tool's CMD_START since."""
        return self.commands.taken_over

    @property
    def client_count(self) -> int:
        with self._lock:
            return len(self._clients)

    # ------------------------------------------------------------------ the session's side (its reader thread)
    def on_received(self, received: Received) -> None:
        frame = received.frame
        message = frame.message
        if isinstance(message, m.Ack):
            self.commands.answer(message)
            return
        if isinstance(message, m.Timesync):
            return  # the run's own clock exchange; a tool's TIMESYNC is answered by the hub (_answer_timesync)
        entry = frame_entry((frame.msg_id, frame.payload, frame.flags & _KEPT_FLAGS))  # one for every tool's queue
        for client in self._fanout:
            client.outbox.put_frame(entry)  # type: ignore[union-attr]  # every tool in _fanout has its outbox

    def on_sent(self, sent: Sent) -> None:
        self.commands.on_sent(sent)

    def on_event(self, event: LinkEvent) -> None:
        if event.kind not in FANNED_OUT:
            return  # the run's own link's life (lost, restored, stats): each tool has its own link to the hub
        text = ground_text(event.kind, event.detail, event.data)
        for client in self._fanout:
            client.queue(text, GROUND_FLAG)

    # ------------------------------------------------------------------ the clients' side (the hub's thread)
    def _wake(self) -> None:
        with contextlib.suppress(OSError):
            self._wake_w.send(b"\0")

    def _serve(self) -> None:
        while not self._stop.is_set():
            now_s = time.monotonic()
            with self._lock:
                slow = [c for c in self._clients if not c.attached and now_s - c.accepted_s > HANDSHAKE_S]
                ended = [c for c in self._clients if c.outbox is not None and c.outbox.ended]
            for late in slow:
                self._drop(late)
            for gone in ended:  # dropped for falling behind (told why), or its socket failed
                self._drop(gone)
            self._reap()
            for key, mask in self._selector.select(0.2):
                if key.fileobj is self._listener:
                    self._accept()
                elif key.fileobj is self._wake_r:
                    with contextlib.suppress(OSError):
                        self._wake_r.recv(4096)
                else:
                    client: _Client = key.data
                    if mask & selectors.EVENT_READ:
                        self._read(client)

    def _accept(self) -> None:
        try:
            sock, peer = self._listener.accept()
        except OSError:
            return
        if peer_is_owner(sock) is False:
            # another user's process: it cannot hold the token (the announcement is 0600), and it must not take
            # the slots the owner's `dive surface` needs (issue 38 N2); where the kernel cannot tell, the token decides
            self.refused_users += 1
            with contextlib.suppress(OSError):
                sock.close()
            return
        with self._lock:
            full = len(self._clients) >= MAX_CLIENTS
            waiting = [c for c in self._clients if not c.attached]
        if full and waiting:
            # the oldest connection still in its handshake makes room: a flood of junk (or of slow handshakes) under
            # load must not keep the owner's `dive surface` out, and a real tool's handshake takes a round trip
            # (one that never sent a valid greeting before one mid-handshake: a tool's proof may be on its way)
            self._drop(min(waiting, key=lambda c: (c.handshake.greeted, c.accepted_s)))
            full = False
        if full:  # every slot a tool that proved the token: the new one is told why, and asks again
            with contextlib.suppress(OSError):
                sock.setblocking(False)
                sock.send(HUB_FULL)
            with contextlib.suppress(OSError):
                sock.close()
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        client = _Client(sock, f"{peer[0]}:{peer[1]}", HubSide(self._token), key=self.session.config.key)
        with self._lock:
            self._clients.append(client)
        self.clients_served += 1
        self._selector.register(sock, selectors.EVENT_READ, client)

    def _drop(self, client: _Client) -> None:
        with self._lock:
            if client not in self._clients:
                return
            self._clients.remove(client)
            self._fanout = tuple(c for c in self._fanout if c is not client)
            self.commands.forget(client)
            if client.outbox is not None:
                self._closing.append(client)
        if client.outbox is not None and client.outbox.too_slow:
            self.dropped_slow += 1
        with contextlib.suppress(KeyError, ValueError, OSError):
            self._selector.unregister(client.sock)
        if client.outbox is None:
            with contextlib.suppress(OSError):
                client.sock.close()
            return
        self._shut(client)  # its writer, blocked in a send or waiting, ends on this
        client.outbox.close(0)

    @staticmethod
    def _shut(client: _Client) -> None:
        with contextlib.suppress(OSError):
            client.sock.shutdown(socket.SHUT_RDWR)

    def _reap(self) -> None:
        """Close the sockets of dropped tools whose writer thread has ended (never before: its fd could be reused)."""
        with self._lock:
            done = [c for c in self._closing if c.outbox is None or c.outbox.ended]
            self._closing = [c for c in self._closing if c not in done]
        for client in done:
            with contextlib.suppress(OSError):
                client.sock.close()

    def _read(self, client: _Client) -> None:
        try:
            data = client.sock.recv(65536)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:
            data = b""
        if not data:
            self._drop(client)
            return
        if not client.attached:
            try:
                reply, data = client.handshake.feed(data)
                if reply:
                    client.sock.send(reply)  # one short line to an empty socket: it fits, or it is no tool
            except (HubAuthError, OSError):
                self._drop(client)  # no token: not one byte reaches the decoder, let alone the agent
                return
            if client.attached:
                client.outbox = ToolOutbox(client.sock, client.encoder, "dive-hub-tool", self._wake,
                                           self.tool_queue_frames)
            if not data:
                return
        rejects = client.decoder.stats.rejects
        for frame in client.decoder.feed(data):
            self._from_client(client, frame.message, frame.seq, frame.inner, frame.flags)
        client.rejects += client.decoder.stats.rejects - rejects
        if client.rejects > MAX_REJECTS:
            self._drop(client)

    def _from_client(self, client: _Client, message: Message, seq: int, inner: bytes, flags: int = 0) -> None:
        if isinstance(message, m.Hello):
            hello = self.session.agent_hello
            with self._lock:
                client.tool = one_line(message.name) or client.tool
                if hello is not None:
                    client.queue(hello)
                if not client.hello_seen and client in self._clients:
                    client.hello_seen = True
                    self._fanout += (client,)  # the agent's HELLO first, then its frames
        elif isinstance(message, m.Text) and flags & GROUND_FLAG:
            request = parse_ground_text(message.text, (ACK_REQUEST,))
            if request is not None and self.acknowledge is not None:
                line = self.acknowledge(client.tool)
                with self._lock:
                    client.queue(m.Text(t_us=time.time_ns() // 1000, severity=1, text=line))
        elif isinstance(message, m.Text):
            self.session.mark(message.text, by=client.tool)
            self.markers += 1
            client.queue(m.Text(t_us=time.time_ns() // 1000, severity=1, text=MARKER_CONFIRMATION))
        elif isinstance(message, m.Timesync):
            if message.receive_us == 0 and message.transmit_us == 0:
                self._answer_timesync(client, message)
        elif isinstance(message, m.LogRequest):
            # The run backfills for every tool (replayed frames are fanned out); a tool's own request is answered
            # from the run's history (run/history.py), never from the on-board log over the agent's one link.
            self._replay_history(client, message, seq)
        elif type(message) in FORWARDED:
            self.commands.command(client, message, seq, inner)
        elif not isinstance(message, m.Heartbeat | m.Ack):
            client.rejects += 1  # an agent's message from a tool: not for the agent
        # HEARTBEAT and ACK from a tool: the run's own session speaks for the ground

    def _answer_timesync(self, client: _Client, request: m.Timesync) -> None:
        """The agent's time now, from the run's clock model: the tool's answer without a frame to the agent."""
        host_us = time.time_ns() // 1000
        offset = self.session.clock.offset_at(host_us)
        if offset is None:
            return  # not synced yet: the tool asks again in a second
        agent_us = int(host_us + offset)
        if 0 < agent_us < _U64_MAX:
            with self._lock:
                client.queue(m.Timesync(origin_us=request.origin_us, receive_us=agent_us, transmit_us=agent_us))

    def _replay_history(self, client: _Client, request: m.LogRequest, seq: int) -> None:
        ack = m.Ack(cmd_msg_id=request.MSG_ID, cmd_seq=seq, result=int(AckResult.ACCEPTED), reason="")
        history = self.history
        frames = history.replay(request.first_sample, request.end_sample) if history is not None else []
        client.queue(ack)
        if client.outbox is not None and frames:
            client.outbox.frames(frames, _KEPT_FLAGS)  # encoded by the tool's writer, holding nothing the run needs
        if history is not None:
            client.queue(history.log_range(len(frames)))
