"""The agent's side of the protocol: HELLO, HEARTBEAT, TIMESYNC, commands with ACK/NACK, dumps, log replay."""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from learning import n_states
from protocol import AckResult, DumpKind, Frame, FrameEncoder, FrameFlag, StreamDecoder, messages
from protocol.decoder import COMMAND_IDS_FROM, UndecodedCommand
from protocol.frame import HEADER
from protocol.registry import Message
from simulator.agent import dumps as agent_dumps
from simulator.agent.dumps import DumpStore
from simulator.agent.identity import HELLO_REPEAT_S, agent_hello
from simulator.agent.link_signing import RESYNCED, UNVERIFIED_SURFACE, LinkSigning, is_resync
from simulator.agent.log_ring import LogRing
from simulator.agent.program import OnboardProgram, Verdict
from simulator.errors import ParamsError

ACK_MEMORY = 16  # SPEC s. 5: the last 16 (msg_id, seq, result) answered on their merits
LOG_REPLAY_SAMPLES = 512  # SPEC s. 7: one LOG_REQUEST replays at most this many SAMPLE records
_DUMP_KINDS = {int(k) for k in DumpKind}
_ACK_ID = messages.Ack.MSG_ID

@dataclass
class LinkWire:
    """The link's frame counter and receive side, and the connection's state: what the program's link takes over
    from whoever spoke for the agent before it existed (serve/starting.py), so no frame is lost or numbered twice."""

    encoder: FrameEncoder = field(default_factory=FrameEncoder)
    decoder: StreamDecoder = field(default_factory=lambda: StreamDecoder(agent=True))
    boot_id: int = field(default_factory=lambda: int.from_bytes(os.urandom(4), "little") or 1)
    connected: bool = False
    heard: bool = False  # a ground frame passed the CRC and version checks on this connection


# A command's verdict and what follows its ACK: messages, or inner frames of the on-board log to replay.
Outcome = tuple[Verdict, list[Message | bytes]]
Handler = Callable[[Message], Outcome]


class AgentLink:
    """Turns received bytes into actions of the program and the program's messages into frames.

    `write` takes wire bytes (the server passes them through fault injection to the transport). `link_clock_s`
    is the link's real clock (SPEC s. 4, time base): link silence, the HELLO repeat and the signing checks use it.
    With a key, `mark_file` keeps the signing mark across restarts (SPEC s. 12). `wire`: the frame counter, receive
    side and connection state to carry on with (a starting agent's); a fresh one by default.
    """

    def __init__(self, write: Callable[[bytes], None], node_id: int, ring: LogRing | None = None,
                 key: bytes | None = None, link_clock_s: Callable[[], float] | None = None,
                 mark_file: Path | None = None, wire: LinkWire | None = None) -> None:
        wire = wire or LinkWire()
        self.write = write
        self.link_clock_s = link_clock_s or self._agent_clock_s
        # With a key, commands must be signed (SPEC s. 12); refusals are counted in HEARTBEAT.signing_rejects.
        self.signing = LinkSigning(key, mark_file) if key is not None else None
        self.signing_rejects = 0
        self.node_id = node_id
        self.boot_id = wire.boot_id
        self.ring = ring or LogRing()
        self.decoder = wire.decoder
        self.dumps = DumpStore()
        self.program: OnboardProgram | None = None
        self._encoder = wire.encoder  # the agent's seq counter; frames keep their inner bytes for the log
        # (msg_id, seq) -> (result, reason), oldest first: one lookup per command, not a scan of all 16
        self._answered: dict[tuple[int, int], tuple[int, str]] = {}
        self._wire = wire  # the connection's state is taken from it again at take_over()
        self._connected = wire.connected
        self._heard = wire.heard  # a frame from the ground passed CRC and version checks on this link
        self._next_hello_s = 0.0
        self._last_ground_rx_s = 0.0
        self._next_heartbeat_us = 0
        # While a command runs, what the program sends waits here: SPEC s. 5 puts the ACK first, so a
        # client sees e.g. CMD_START's ACK before the EPISODE_START it causes.
        self._deferred: list[Callable[[], None]] | None = None
        self._handlers: dict[type[Message], Handler] = {
            messages.StartLearning: self._start, messages.Stop: self._simple("stop"),
            messages.Pause: self._simple("pause"), messages.SetTarget: self._set_target,
            messages.Surface: self._surface, messages.Hover: self._hover, messages.DumpRequest: self._dump,
            messages.ResetModel: self._simple("reset_model"), messages.ParamListRequest: self._param_list,
            messages.ParamGet: self._param_get, messages.ParamSet: self._param_set,
            messages.LogRequest: self._log_request,
        }

    @property
    def next_seq(self) -> int:
        return self._encoder.next_seq

    @property
    def encoder(self) -> FrameEncoder:
        """The agent's frame encoder (its seq counter), for compiled batches that frame SAMPLEs themselves."""
        return self._encoder

    @property
    def heartbeat_due_us(self) -> int:
        """Agent time from which the next tick() sends a HEARTBEAT."""
        return self._next_heartbeat_us

    @property
    def uses_agent_clock(self) -> bool:
        """The link clock is the agent's own (real-time speeds), not the wall clock."""
        return self.link_clock_s == self._agent_clock_s

    @property
    def last_ground_rx_s(self) -> float:
        """Link-clock time of the last sign of life from the ground."""
        return self._last_ground_rx_s

    def attach(self, program: OnboardProgram) -> None:
        self.program = program
        self._last_ground_rx_s = self.link_clock_s()

    def take_over(self) -> None:
        """The program runs from now on (it was built while a starting agent spoke): the connection as the starting
        agent leaves it (a client may have come, spoken or gone during the build), the ground's silence counted from
        here, not from the build's start, and a HELLO repeat under way carried on at its pace."""
        self._connected, self._heard = self._wire.connected, self._wire.heard
        self._encoder.compiled = self.decoder.compiled = True  # off while the starting agent spoke
        self._alive()
        self._next_hello_s = self.link_clock_s() + HELLO_REPEAT_S

    def _agent_clock_s(self) -> float:
        return self._prog.t_us / 1e6 if self.program is not None else 0.0

    def link_silence_s(self) -> float:
        """Link-clock seconds since the last sign of life from the ground (SPEC s. 4, link loss)."""
        return self.link_clock_s() - self._last_ground_rx_s

    def model_changed(self) -> None:
        """The learner's model changed: a COUNTS snapshot, rendered from the live model, is now STALE."""
        self.dumps.model_changed()

    @property
    def _prog(self) -> OnboardProgram:
        assert self.program is not None, "attach() the program first"
        return self.program

    # ------------------------------------------------------------------ sending
    def send(self, message: Message, flags: int = 0) -> None:
        self.send_payload(message.MSG_ID, message.pack(), flags)

    def send_payload(self, msg_id: int, payload: bytes, flags: int = 0) -> None:
        """send() for a payload already packed (the ACK of every command, packed from its values)."""
        if self._deferred is not None:
            self._deferred.append(lambda: self.send_payload(msg_id, payload, flags))
            return
        self.write(self._encoder.encode_payload(msg_id, payload, flags).wire)

    def log_frame(self, message: Message, sample: int, is_sample: bool) -> None:
        """A SAMPLE or EPISODE frame: into the on-board log, then onto the link."""
        self.log_payload(message.MSG_ID, message.pack(), sample, is_sample)

    def log_payload(self, msg_id: int, payload: bytes, sample: int, is_sample: bool) -> None:
        """log_frame for an already packed payload (the SAMPLE of every control step)."""
        if self._deferred is not None:
            self._deferred.append(lambda: self.log_payload(msg_id, payload, sample, is_sample))
            return
        inner = self._encoder.next_inner(msg_id, payload)
        self.ring.append(sample, inner, is_sample)
        self.write(self._encoder.wire(inner))

    def episode_dumps(self) -> None:
        for kind in (DumpKind.VALUES, DumpKind.POLICY):
            for chunk in agent_dumps.chunks(self.dumps.take(self._prog.learner, kind), 0, 0):
                self.send(chunk)

    def hello(self) -> None:
        self._next_hello_s = self.link_clock_s() + HELLO_REPEAT_S
        self.send(agent_hello(self.node_id, self.boot_id, self._prog.generation))

    def heartbeat(self) -> None:
        prog, stats = self._prog, self.decoder.stats
        self.send(messages.Heartbeat(
            uptime_ms=(prog.t_us // 1000) & 0xFFFFFFFF, mode=int(prog.mode),
            battery_mv=int(prog.hw.battery_v * 1000), rx_frames=stats.frames, rx_rejects=stats.rejects,
            rx_lost=stats.lost, log_first_sample=self.ring.first_sample, log_next_sample=prog.next_sample,
            episode=prog.episode, signing_rejects=self.signing_rejects & 0xFFFFFFFF, generation=prog.generation,
        ))

    def tick(self) -> None:
        """Called after every control step: HEARTBEAT once per second of agent time."""
        prog = self._prog
        if prog.t_us >= self._next_heartbeat_us:
            self._next_heartbeat_us = prog.t_us + int(prog.mission.heartbeat_period_s * 1e6)
            self.heartbeat()

    def service(self) -> None:
        """Called every loop of the server: the HELLO repeat until the ground is heard (SPEC s. 4)."""
        if self._connected and not self._heard and self.link_clock_s() >= self._next_hello_s:
            self.hello()

    # ------------------------------------------------------------------ receiving
    def on_connect(self) -> None:
        """A new link: sequence tracking starts over, and the agent introduces itself until it hears the ground."""
        self.decoder.reset_sequence()
        self._answered.clear()  # SPEC 1.2 s. 5: a new session's seqs must not meet the last one's ACKs
        self._connected, self._heard = True, False
        self.hello()

    def on_disconnect(self) -> None:
        self._connected = False

    def receive(self, data: bytes) -> None:
        """Whatever the link delivered; garbage is counted by the decoder and otherwise ignored."""
        for frame in self.decoder.feed(data):
            self._heard = True
            if frame.msg_id >= COMMAND_IDS_FROM:
                self._command(frame)
            elif self._admitted(frame):  # an unsigned frame must not keep a signed link alive
                self._alive()
                self._handle(frame)
            else:
                self._handle(frame)

    def _alive(self) -> None:
        self._last_ground_rx_s = self.link_clock_s()

    def _admitted(self, frame: Frame) -> bool:
        """A non-command frame counts as a sign of life: any, or with a key only a validly signed one."""
        return self.signing is None or self.signing.admits(frame, self.link_clock_s())

    def _handle(self, frame: Frame) -> None:
        message = frame.message
        if isinstance(message, messages.Hello):  # SPEC s. 4: every ground HELLO is answered
            self._answered.clear()  # SPEC 1.2 s. 5: a ground HELLO starts a session, with an empty ACK memory
            self.hello()
        elif isinstance(message, messages.Timesync):
            if message.receive_us == 0 and message.transmit_us == 0:
                t = self._prog.t_us
                # SPEC s. 9: a reply never carries transmit_us = 0 (it would read as a request)
                self.send(messages.Timesync(origin_us=message.origin_us, receive_us=t, transmit_us=max(t, 1)))

    def _refuse(self, frame: Frame, why: str) -> None:
        """UNAUTHORIZED: not run, not remembered in the ACK memory, counted (SPEC s. 5, 12)."""
        self.signing_rejects += 1
        self._ack(frame, AckResult.UNAUTHORIZED, why)

    def _command(self, frame: Frame) -> None:
        """SPEC s. 5, order of checks: truncated, HMAC, ACK memory, timestamp, unknown id, the command itself.

        CMD_SURFACE is exempt from the signature checks (SPEC 1.2 s. 12, emergencies): surfacing is the fail-safe
        state, so anyone may make the agent surface (nobody may make it dive). Its ACK says it ran unverified.
        """
        message, signing = frame.message, self.signing
        if signing is None:  # without a key every frame counted in rx_frames is a sign of life (SPEC s. 4)
            self._alive()
        if isinstance(message, UndecodedCommand) and message.truncated:
            self._refuse(frame, "truncated signature")
            return
        unverified = ""
        if signing is not None:
            refused, unverified = signing.authenticate(frame)
            if refused:
                self._refuse(frame, refused)
                return
        answered = self._answered.get((frame.msg_id, frame.seq))
        if answered is not None:
            self._ack(frame, AckResult(answered[0]), answered[1])  # a retry: answer again, do not act again
            return
        if signing is not None and not unverified:
            if is_resync(message):
                self._resync(frame, signing)
                return
            refused, unverified = signing.admit(frame, self.link_clock_s())
            if refused:
                self._refuse(frame, refused)
                return
            if not unverified:
                self._alive()
        self._execute(frame, f"{UNVERIFIED_SURFACE} ({unverified})" if unverified else "")

    def _resync(self, frame: Frame, signing: LinkSigning) -> None:
        """The signed re-sync (SPEC s. 12), authenticated already: ACCEPTED and remembered, or refused."""
        refused = signing.resync(frame, self.link_clock_s())
        if refused:
            self._refuse(frame, refused)
            return
        self._alive()
        self._remember(frame, AckResult.ACCEPTED, RESYNCED)
        self._ack(frame, AckResult.ACCEPTED, RESYNCED)

    def _remember(self, frame: Frame, result: AckResult, reason: str) -> None:
        """The ACK memory (SPEC s. 5): a retry of this (msg_id, seq) is answered the same, not run again."""
        answered = self._answered
        answered[(frame.msg_id, frame.seq)] = (int(result), reason)
        if len(answered) > ACK_MEMORY:
            del answered[next(iter(answered))]

    def _execute(self, frame: Frame, note: str = "") -> None:
        """Run a command and ACK it; `note` replaces an ACCEPTED's empty reason (an unverified CMD_SURFACE)."""
        handler = self._handlers.get(type(frame.message))
        self._prog.finish_command()  # an earlier command of the same read (a learner restart) takes effect first
        replies: list[Message | bytes] = []
        self._deferred = []
        try:
            if handler is not None:
                (result, reason), replies = handler(frame.message)
            else:
                result, reason = AckResult.UNSUPPORTED, f"command 0x{frame.msg_id:02X} not implemented"
        finally:
            deferred, self._deferred = self._deferred, None
        if note and result == AckResult.ACCEPTED:
            reason = note
        self._remember(frame, result, reason)
        self._ack(frame, result, reason)
        for action in deferred:
            action()
        for reply in replies:
            if isinstance(reply, bytes):
                # Re-sent as logged (same msg_id and payload), flagged REPLAYED, with a new seq.
                msg_id = reply[HEADER.size - 1]
                replayed = self._encoder.encode_payload(msg_id, reply[HEADER.size : -2], FrameFlag.REPLAYED)
                self.write(replayed.wire)
            else:
                self.send(reply)

    def _ack(self, frame: Frame, result: AckResult, reason: str) -> None:
        self.send_payload(_ACK_ID, messages.Ack.pack_values(frame.msg_id, frame.seq, int(result), reason))

    # ------------------------------------------------------------------ command handlers
    def _simple(self, name: str) -> Handler:
        def handler(_: Message) -> Outcome:
            return getattr(self._prog, name)(), []
        return handler

    def _start(self, m: Message) -> Outcome:
        assert isinstance(m, messages.StartLearning)
        return self._prog.start(m.max_episodes), []

    def _surface(self, _: Message) -> Outcome:
        self._prog.surface("CMD_SURFACE")
        return (AckResult.ACCEPTED, ""), []

    def _hover(self, m: Message) -> Outcome:
        assert isinstance(m, messages.Hover)
        return self._prog.hover(m.depth_m), []

    def _set_target(self, m: Message) -> Outcome:
        assert isinstance(m, messages.SetTarget)
        index = self._prog.table.lookup(-1, "target_depth_m")
        return self._prog.set_param(index, m.target_depth_m), []

    def _param_list(self, _: Message) -> Outcome:
        table = self._prog.table
        return (AckResult.ACCEPTED, ""), [table.message(i) for i in range(len(table))]

    def _param_get(self, m: Message) -> Outcome:
        assert isinstance(m, messages.ParamGet)
        try:
            index = self._prog.table.lookup(m.index, m.name)
        except ParamsError as e:
            return (AckResult.BAD_VALUE, str(e)), []
        return (AckResult.ACCEPTED, ""), [self._prog.table.message(index)]

    def _param_set(self, m: Message) -> Outcome:
        assert isinstance(m, messages.ParamSet)
        table = self._prog.table
        try:
            index = table.lookup(m.index, m.name)
        except ParamsError as e:
            return (AckResult.BAD_VALUE, str(e)), []
        verdict = self._prog.set_param(index, m.value)
        return verdict, [table.message(index)] if verdict[0] == AckResult.ACCEPTED else []

    def _dump(self, m: Message) -> Outcome:
        assert isinstance(m, messages.DumpRequest)
        if m.kind not in _DUMP_KINDS:
            return (AckResult.BAD_VALUE, f"no dump kind {m.kind}"), []
        held = None
        if m.dump_id == 0:
            size = agent_dumps.snapshot_size(n_states(self._prog.config), DumpKind(m.kind))
        else:
            held = self.dumps.get(m.dump_id)
            if held is None or held.kind != m.kind:
                return (AckResult.STALE, f"dump {m.dump_id} no longer held"), []
            size = len(held.data)
        if m.offset > size:  # SPEC 1.2 s. 10: refused before a snapshot is taken (no id, no place used)
            return (AckResult.BAD_VALUE, f"offset {m.offset} past the {size}-byte snapshot"), []
        snap = held if held is not None else self.dumps.take(self._prog.learner, DumpKind(m.kind))
        # All chunks are rendered here, before the next control step: a live snapshot is never sent as a mix of
        # two models (SPEC 1.2 s. 10); the link paces them out afterwards.
        return (AckResult.ACCEPTED, ""), list(agent_dumps.chunks(snap, m.offset, m.length))

    def _log_request(self, m: Message) -> Outcome:
        assert isinstance(m, messages.LogRequest)
        records = self.ring.records(m.first_sample, m.end_sample, LOG_REPLAY_SAMPLES)
        replies: list[Message | bytes] = [r.inner for r in records]
        ring = self.ring
        replies.append(messages.LogRange(
            first_sample=ring.first_sample, next_sample=ring.next_sample, replayed=len(records),
            bytes_used=ring.bytes_used, capacity_bytes=ring.capacity_bytes,
        ))
        return (AckResult.ACCEPTED, ""), replies

