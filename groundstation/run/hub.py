"""The hub: a running `dive run` shares its one session with the agent with local tools (as MAVProxy's outputs).

The agent has one TCP slot (so does the ESP8266 bridge); a second tool connecting to it would take the link
from the run. Instead the run's session re-serves the agent's frames on a loopback TCP port, in the agent's
own protocol, so `dive view`, `status`, `mark`, `surface`, ... attach with the same link code as to an agent:

- a connection first proves it holds the run's token (links/hub_auth.py); anything else is closed unanswered;
- every frame the session delivers is fanned out to every client, re-framed with the client's own seq
  (the REPLAYED flag kept), so a client's loss count is its own link's; TIMESYNC answers (the run's) are not;
- a client's HELLO is answered with the agent's HELLO, its HEARTBEATs are dropped (the run sends its own);
- a client's command is checked (run/hub_clients.py: a command, signed when the run is, within its limits), then sent
  to the agent by the session, with the session's seq and signature, once (a client's retry of the same seq is not
  sent again); the agent's ACK goes back to that client with the client's seq;
- a client's TIMESYNC request is answered by the hub from the run's clock model: no tool's TIMESYNC reaches the agent;
- a client's TEXT is a marker for the run's recording (`dive mark`), confirmed by a TEXT back; a ground-flagged
  TEXT `ack` acknowledges the run's alarms (`dive ack`, run/alarms.py), answered by a TEXT saying what was;
- every command a tool sends is echoed once answered, as a `command` event (run/echo.py): who sent what, the answer;
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
from collections import OrderedDict
from collections.abc import Callable

from groundstation.errors import LinkError
from groundstation.links.hub_auth import FULL as HUB_FULL
from groundstation.links.hub_auth import HubAuthError, HubSide
from groundstation.links.hub_events import ACK_REQUEST, FANNED_OUT, GROUND_FLAG, ground_text, parse_ground_text
from groundstation.links.peer import peer_is_owner
from groundstation.run.echo import echo
from groundstation.run.history import History
from groundstation.run.hub_clients import EMERGENCY, FORWARDED, HANDSHAKE_S, MAX_CLIENTS, MAX_REJECTS, HubClient
from groundstation.run.hub_outbox import TOOL_QUEUE_FRAMES, ToolOutbox, frame_entry
from groundstation.run.marker import CONFIRMATION as MARKER_CONFIRMATION
from groundstation.safe_output import one_line
from groundstation.session.agent_session import Session
from groundstation.session.events import EventKind, LinkEvent, Received, Sent
from protocol import AckResult, FrameFlag, Message
from protocol import messages as m

FORWARDED_MEMORY = 256  # forwarded commands remembered (for ACK mapping and client retries)
_KEPT_FLAGS = int(FrameFlag.REPLAYED)  # of an agent frame; the rest (GROUND_FLAG too) cleared: no forged events
_TAKE_OVER_IDS = {kind.MSG_ID: kind.DEFINITION.name for kind in (m.Surface, m.Stop, m.Hover, m.Pause)}
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
        # session seq of a forwarded command -> (client, client seq); and the client's retries -> session seq
        self._by_session_seq: OrderedDict[tuple[int, int], tuple[_Client, int, Message]] = OrderedDict()
        self._by_client_seq: OrderedDict[tuple[int, int, int], tuple[int, m.Ack | None]] = OrderedDict()
        self._forwarding: Message | None = None
        self._forwarded_seq: int | None = None
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._serve, name="dive-hub", daemon=True)
        self.markers = 0
        self.clients_served = 0
        self.refused_users = 0  # connections from another user's processes, closed at accept
        self.dropped_slow = 0  # tools dropped for falling a whole queue behind (run/hub_outbox.py)
        # The last command a tool sent that takes the agent out of learning (CMD_SURFACE, STOP, HOVER, PAUSE), or
        # None after a tool's CMD_START: the run must not start learning again behind an operator's back.
        self.taken_over: str | None = None
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
    def client_count(self) -> int:
        with self._lock:
            return len(self._clients)

    # ------------------------------------------------------------------ the session's side (its reader thread)
    def on_received(self, received: Received) -> None:
        frame = received.frame
        message = frame.message
        if isinstance(message, m.Ack):
            self._answer_forwarded(message)
            return
        if isinstance(message, m.Timesync):
            return  # the run's own clock exchange; a tool's TIMESYNC is answered by the hub (_answer_timesync)
        entry = frame_entry((frame.msg_id, frame.payload, frame.flags & _KEPT_FLAGS))  # one for every tool's queue
        for client in self._fanout:
            client.outbox.put_frame(entry)  # type: ignore[union-attr]  # every tool in _fanout has its outbox

    def on_sent(self, sent: Sent) -> None:
        if self._forwarding is not None and sent.message is self._forwarding:
            self._forwarded_seq = sent.seq

    def on_event(self, event: LinkEvent) -> None:
        if event.kind not in FANNED_OUT:
            return  # the run's own link's life (lost, restored, stats): each tool has its own link to the hub
        text = ground_text(event.kind, event.detail, event.data)
        for client in self._fanout:
            client.queue(text, GROUND_FLAG)

    def _answer_forwarded(self, ack: m.Ack) -> None:
        beat = self.session.last_heartbeat
        with self._lock:
            target = self._by_session_seq.get((ack.cmd_msg_id, ack.cmd_seq))
            if target is None:
                return  # an answer to the run's own command
            client, client_seq, message = target
            first = (id(client), ack.cmd_msg_id, client_seq) in self._by_client_seq and \
                self._by_client_seq[(id(client), ack.cmd_msg_id, client_seq)][1] is None
            client.in_flight.pop((ack.cmd_msg_id, client_seq), None)
            self._note_take_over(ack)
            mapped = m.Ack(cmd_msg_id=ack.cmd_msg_id, cmd_seq=client_seq, result=ack.result, reason=ack.reason)
            key = (id(client), ack.cmd_msg_id, client_seq)
            if key in self._by_client_seq:
                self._by_client_seq[key] = (ack.cmd_seq, mapped)
            if client in self._clients:
                client.queue(mapped)
        said = echo(client.tool, message, ack, beat.mode if beat is not None else None) if first else None
        if said is not None:  # outside the lock: the event comes back to this hub's on_event
            self.session.listeners.event(LinkEvent(EventKind.COMMAND, time.time_ns(), *said))

    def _note_take_over(self, ack: m.Ack) -> None:
        """A tool's accepted CMD_SURFACE / STOP / HOVER / PAUSE takes the agent from the run; its CMD_START hands it
        back. A refused one changes nothing (the agent goes on as it was)."""
        if ack.result != AckResult.ACCEPTED:
            return
        if ack.cmd_msg_id in _TAKE_OVER_IDS:
            self.taken_over = _TAKE_OVER_IDS[ack.cmd_msg_id]
        elif ack.cmd_msg_id == m.StartLearning.MSG_ID:
            self.taken_over = None

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
            for key in [k for k, (c, _, _) in self._by_session_seq.items() if c is client]:
                del self._by_session_seq[key]
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
            self._check_command(client, message, seq, inner)
        elif not isinstance(message, m.Heartbeat | m.Ack):
            client.rejects += 1  # an agent's message from a tool: not for the agent
        # HEARTBEAT and ACK from a tool: the run's own session speaks for the ground

    def _check_command(self, client: _Client, message: Message, seq: int, inner: bytes) -> None:
        # CMD_SURFACE from the owner's tool (it proved the token) needs no signature: a keyed agent runs it unsigned on
        # purpose (SPEC 1.2), and `dive surface` without the key must work through the run too (issue 38 N9)
        problem = None if isinstance(message, EMERGENCY) else client.signature_problem(inner)
        if problem is not None:
            with self._lock:
                client.refuse(message, seq, AckResult.UNAUTHORIZED, problem)
            return
        with self._lock:
            retry = (id(client), message.MSG_ID, seq) in self._by_client_seq  # answered or in flight: no new one
            if not isinstance(message, EMERGENCY) and not retry and client.busy(time.monotonic()):
                client.refuse(message, seq, AckResult.BUSY, "too many commands in flight from this tool")
                return
        self._forward_command(client, message, seq)

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

    def _forward_command(self, client: _Client, message: Message, seq: int) -> None:
        key = (id(client), message.MSG_ID, seq)
        # Under the lock from sending to filing the seq: the agent's ACK can come back (and be looked up by the
        # session's reader thread in _answer_forwarded) before session.send has even returned.
        with self._lock:
            known = self._by_client_seq.get(key)
            if known is not None:
                _, ack = known
                if ack is not None:  # a retry after the ACK was lost: answer it again, do not act twice
                    client.queue(ack)
                return  # still in flight: the session retries it itself
            session_seq = self._send(message)
            if session_seq is None:
                return  # the link is down; the client's retry will try again
            client.in_flight[(message.MSG_ID, seq)] = time.monotonic()
            self._by_session_seq[(message.MSG_ID, session_seq)] = (client, seq, message)
            self._by_client_seq[key] = (session_seq, None)
            for table in (self._by_session_seq, self._by_client_seq):
                while len(table) > FORWARDED_MEMORY:
                    table.popitem(last=False)  # type: ignore[call-arg]

    def _send(self, message: Message) -> int | None:
        """Send through the session; the seq it used (seen by on_sent in this thread), None if the link is down."""
        self._forwarding, self._forwarded_seq = message, None
        try:
            self.session.send(message, wait=False)
        except LinkError:
            return None
        finally:
            self._forwarding = None
        return self._forwarded_seq
