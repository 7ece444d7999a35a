"""A tool's command through the hub (run/hub.py) to the agent, and the agent's ACK back to that tool.

A command is checked (run/hub_clients.py: signed when the run is, within the tool's in-flight limit; CMD_SURFACE
always passes), then sent by the run's session with the session's seq and signature, once: a tool's retry of the
same seq is answered from what is remembered, not sent again. The agent's ACK goes back to the tool with the tool's
seq, and each command is echoed once answered, as a `command` event (run/echo.py). An accepted CMD_SURFACE, STOP,
HOVER or PAUSE takes the agent from the run (`taken_over`); a tool's CMD_START hands it back.
"""

from __future__ import annotations

import threading
import time
from collections import OrderedDict
from collections.abc import Callable

from groundstation.errors import LinkError
from groundstation.run.echo import echo
from groundstation.run.hub_clients import EMERGENCY, HubClient
from groundstation.session.agent_session import Session
from groundstation.session.events import EventKind, LinkEvent, Sent
from protocol import AckResult, Message
from protocol import messages as m

FORWARDED_MEMORY = 256  # forwarded commands remembered (for ACK mapping and client retries)
_TAKE_OVER_IDS = {kind.MSG_ID: kind.DEFINITION.name for kind in (m.Surface, m.Stop, m.Hover, m.Pause)}


class CommandForwarder:
    """The hub's commands in flight. `lock` is the hub's (it guards the tools' queues as well); `attached(client)`
    says whether a tool is still attached (its answer is queued only then)."""

    def __init__(self, session: Session, lock: threading.Lock, attached: Callable[[HubClient], bool]) -> None:
        self.session = session
        self._lock = lock
        self._attached = attached
        # session seq of a forwarded command -> (client, client seq); and the client's retries -> session seq
        self._by_session_seq: OrderedDict[tuple[int, int], tuple[HubClient, int, Message]] = OrderedDict()
        self._by_client_seq: OrderedDict[tuple[int, int, int], tuple[int, m.Ack | None]] = OrderedDict()
        self._forwarding: Message | None = None
        self._forwarded_seq: int | None = None
        # The last command a tool sent that takes the agent out of learning (CMD_SURFACE, STOP, HOVER, PAUSE), or
        # None after a tool's CMD_START: the run must not start learning again behind an operator's back.
        self.taken_over: str | None = None

    # ------------------------------------------------------------------ the session's side (its reader thread)
    def on_sent(self, sent: Sent) -> None:
        if self._forwarding is not None and sent.message is self._forwarding:
            self._forwarded_seq = sent.seq

    def answer(self, ack: m.Ack) -> None:
        """The agent's ACK: back to the tool whose command it answers (nothing if it answers the run's own)."""
        beat = self.session.last_heartbeat
        with self._lock:
            target = self._by_session_seq.get((ack.cmd_msg_id, ack.cmd_seq))
            if target is None:
                return  # an answer to the run's own command
            client, client_seq, message = target
            key = (id(client), ack.cmd_msg_id, client_seq)
            first = key in self._by_client_seq and self._by_client_seq[key][1] is None
            client.in_flight.pop((ack.cmd_msg_id, client_seq), None)
            self._note_take_over(ack)
            mapped = m.Ack(cmd_msg_id=ack.cmd_msg_id, cmd_seq=client_seq, result=ack.result, reason=ack.reason)
            if key in self._by_client_seq:
                self._by_client_seq[key] = (ack.cmd_seq, mapped)
            if self._attached(client):
                client.queue(mapped)
        said = echo(client.tool, message, ack, beat.mode if beat is not None else None) if first else None
        if said is not None:  # outside the lock: the event comes back to the hub's on_event
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

    # ------------------------------------------------------------------ the tools' side (the hub's thread)
    def forget(self, client: HubClient) -> None:
        """A dropped tool: its commands' ACKs have no one to go to. Call with the hub's lock held."""
        for key in [k for k, (c, _, _) in self._by_session_seq.items() if c is client]:
            del self._by_session_seq[key]

    def command(self, client: HubClient, message: Message, seq: int, inner: bytes) -> None:
        """A tool's command: refused with its reason, answered again (a retry), or sent to the agent."""
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
        self._forward(client, message, seq)

    def _forward(self, client: HubClient, message: Message, seq: int) -> None:
        key = (id(client), message.MSG_ID, seq)
        # Under the lock from sending to filing the seq: the agent's ACK can come back (and be looked up by the
        # session's reader thread in answer) before session.send has even returned.
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
