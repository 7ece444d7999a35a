"""One tool attached to a run's hub: its handshake, its codecs, and what it may send the agent (issue 25 C1, H1, M1).

A tool's frames are checked before anything reaches the agent: the handshake first (links/hub_auth.py); then only
commands (minus LOG_REQUEST: the run backfills for everyone), each signed with the run's key when the run has one
(the tool holds the key and signs; the run verifies, then sends it with its own seq and signature: the hub never
lends its key), at most MAX_IN_FLIGHT of them unanswered, CMD_SURFACE excepted: an emergency overtakes any limit.
"""

from __future__ import annotations

import socket
import time
from collections import OrderedDict
from dataclasses import dataclass, field

from groundstation.links.hub_auth import HubSide
from groundstation.run.hub_outbox import ToolOutbox
from protocol import AckResult, FrameEncoder, Message, SignatureCheck, SignatureVerifier, StreamDecoder
from protocol import messages as m

MAX_CLIENTS = 16  # connections at once, handshaking or attached: 150 idle ones once took 216 MB and half the speed
HANDSHAKE_S = 3.0  # a connection that has not proved the token by then is closed
MAX_IN_FLIGHT = 4  # unanswered commands a tool may have at once; more are refused BUSY at the hub
IN_FLIGHT_S = 6.0  # a forwarded command unanswered this long no longer counts (the session gave up on it)
MAX_REJECTS = 32  # frames that fail the CRC, name no message, or are not for the agent: a tool sending more is closed
EMERGENCY = (m.Surface,)  # never refused for a limit, never queued behind another tool's commands
FORWARDED = frozenset((m.StartLearning, m.Stop, m.Pause, m.SetTarget, m.Surface, m.Hover, m.DumpRequest,
                       m.ResetModel, m.ParamListRequest, m.ParamGet, m.ParamSet))  # every command but LOG_REQUEST


@dataclass(eq=False)
class HubClient:
    sock: socket.socket
    name: str
    handshake: HubSide
    key: bytes | None = field(default=None, repr=False)
    accepted_s: float = field(default_factory=time.monotonic)
    encoder: FrameEncoder = field(default_factory=FrameEncoder)  # its writer thread's alone, once attached
    decoder: StreamDecoder = field(default_factory=StreamDecoder)
    outbox: ToolOutbox | None = None  # what is sent to it, by a thread of its own (made once it proved the token)
    hello_seen: bool = False
    tool: str = "a tool"  # its HELLO's name ("dive target", "foxglove"): who the run pane says sent a command
    rejects: int = 0
    in_flight: OrderedDict[tuple[int, int], float] = field(default_factory=OrderedDict)  # (msg id, seq) -> sent
    verifier: SignatureVerifier | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.key is not None:  # one per tool: each tool's link id and timestamps are its own
            self.verifier = SignatureVerifier(self.key)

    @property
    def attached(self) -> bool:
        return self.handshake.done

    def queue(self, message: Message, flags: int = 0) -> None:
        if self.outbox is not None:  # nothing is sent to a connection that has not proved the token
            self.outbox.message(message, flags)

    def refuse(self, message: Message, seq: int, result: AckResult, reason: str) -> None:
        """A NACK from the hub itself: the command never reached the agent."""
        self.queue(m.Ack(cmd_msg_id=message.MSG_ID, cmd_seq=seq, result=int(result), reason=reason))

    def busy(self, now_s: float) -> bool:
        """MAX_IN_FLIGHT commands unanswered (those older than IN_FLIGHT_S forgotten first)."""
        while self.in_flight and now_s - next(iter(self.in_flight.values())) > IN_FLIGHT_S:
            self.in_flight.popitem(last=False)
        return len(self.in_flight) >= MAX_IN_FLIGHT

    def signature_problem(self, inner: bytes) -> str | None:
        """Why a command from this tool may not go to a keyed run's agent, or None (also with no key)."""
        if self.verifier is None:
            return None
        result = self.verifier.check(inner, time.monotonic())
        if result is SignatureCheck.VALID:
            return None
        return f"the run is signed: sign with its key (--key-file): {result.name.lower()}"
