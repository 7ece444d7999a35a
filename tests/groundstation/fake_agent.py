"""A small scripted agent for ground-station tests: speaks the protocol over a TCP socket on 127.0.0.1."""

from __future__ import annotations

import socket
import struct
import threading
import time
from collections import deque

from protocol import AckResult, DumpKind, FrameEncoder, FrameFlag, Message, Mode, StreamDecoder, definitions_hash
from protocol import messages as m

PARAMS = [  # name, type, value, min, max
    ("target_depth_m", 5, 0.5, 0.05, 2.0),
    ("z_tol_m", 5, 0.1, 0.01, 0.5),
    ("zdot_tol_mps", 5, 0.05, 0.001, 0.5),
    ("success_time_s", 5, 20.0, 1.0, 600.0),
    ("term_reward", 5, -10.0, -100.0, 0.0),
    ("max_episodes", 4, 0, 0, 100000),
    ("dump_each_episode", 1, 0, 0, 1),
]


class FakeAgent:
    """Streams SAMPLEs, an episode every `episode_len` samples, keeps an on-board log, answers commands."""

    def __init__(self, *, period_s: float = 0.005, episode_len: int = 20, protocol_version: int = 1,
                 defs_hash: int | None = None, drop_every: int = 0, depth_step_m: float = 0.001) -> None:
        self.period_s = period_s
        self.depth_step_m = depth_step_m  # an episode's depth climbs this much a step from 0.5 m
        self.last_dump_id = 6  # snapshot ids count up from 7
        self.episode_len = episode_len
        self.protocol_version = protocol_version
        self.defs_hash = definitions_hash() if defs_hash is None else defs_hash
        self.drop_every = drop_every  # drop every Nth live SAMPLE (it stays in the on-board log)
        self.params = {name: [kind, value, lo, hi] for name, kind, value, lo, hi in PARAMS}
        self.encoder = FrameEncoder()
        self.log: list[tuple[int, Message]] = []
        self.answered: deque[tuple[int, int, int]] = deque(maxlen=16)
        self.executed: list[str] = []
        self.sample = 0
        self.episode = 0
        self.successes = 0
        self.learning = False
        self.max_episodes = 0
        self.ignore_commands = 0  # swallow this many command frames (to exercise retries)
        self.connections = 0  # TCP connections accepted (the agent has one slot: a second one takes it)
        # identity and misbehaviour, for the safety tests (tests/reliability/test_safety_*.py)
        self.name, self.node_id, self.boot_id = "fake", 0xA6E47, 1234
        self.nack_reason = ""  # the reason text of every NACK
        self.refuse = 0  # non-zero: refuse every command (but PARAM_LIST, LOG_REQUEST) with this AckResult
        self.hello_on_accept = True  # send HELLO when a connection comes (else only in answer to the ground's)
        self.unanswered_hellos = 0  # leave this many ground HELLOs unanswered (a HELLO lost on the link)
        self.duplicate_frames = False  # send every live frame twice, byte for byte
        self.replay_limit = 512  # samples replayed per LOG_REQUEST at most (SPEC.md 1.1)
        self.ignored_log_requests = 0  # ACK this many LOG_REQUESTs without replaying (a replay lost each time)
        self.log_requests = 0
        self.timesync_origins: list[int] = []  # the origin of every TIMESYNC request received
        self.lying_timesyncs = 0  # answer this many TIMESYNC requests with receive = transmit = 2^64-1
        self.mode_checks = False  # True: CMD_START while learning is NOT_ALLOWED_IN_MODE (SPEC.md s. 6)
        self.drop_before_ack = ""  # the next command of this name runs, then the link drops before its ACK leaves
        self.live = True  # False: SAMPLE and episode frames go to the on-board log only (a radio blackout)
        self._t0 = time.monotonic()
        self._conn: socket.socket | None = None
        self._lock = threading.RLock()
        self._last_wire = b""
        self._stop = threading.Event()
        self.server = socket.create_server(("127.0.0.1", 0))
        self.url = f"tcp://127.0.0.1:{self.server.getsockname()[1]}"
        self._threads = [threading.Thread(target=self._accept, daemon=True),
                         threading.Thread(target=self._produce, daemon=True)]
        for t in self._threads:
            t.start()

    def close(self) -> None:
        self._stop.set()
        self.disconnect()
        self.server.close()
        for t in self._threads:
            t.join(2)

    def disconnect(self) -> None:
        with self._lock:
            conn, self._conn = self._conn, None
        if conn is not None:
            try:
                conn.shutdown(socket.SHUT_RDWR)
            except OSError:
                pass
            conn.close()

    # ------------------------------------------------------------------ transport
    def _send(self, message: Message, flags: int = 0) -> None:
        with self._lock:
            conn = self._conn
            if conn is None:
                return
            wire = self.encoder.encode(message, flags).wire
            self._last_wire = wire
            try:
                conn.sendall(wire)
            except OSError:
                pass

    def _resend_last(self) -> None:
        with self._lock:
            if self._conn is not None:
                try:
                    self._conn.sendall(self._last_wire)
                except OSError:
                    pass

    def _accept(self) -> None:
        self.server.settimeout(0.1)
        while not self._stop.is_set():
            try:
                conn, _ = self.server.accept()
            except (TimeoutError, OSError):
                continue
            with self._lock:  # the HELLO first, before any HEARTBEAT of the producer (re-entrant: _send takes it)
                self._conn = conn
                self.connections += 1
                self.answered.clear()  # a new session: the ACK memory is emptied (SPEC.md 1.2 s. 5)
                if self.hello_on_accept:
                    self._send_hello()
            threading.Thread(target=self._read, args=(conn,), daemon=True).start()

    def _read(self, conn: socket.socket) -> None:
        decoder = StreamDecoder()
        while not self._stop.is_set():
            try:
                data = conn.recv(4096)
            except OSError:
                return
            if not data:
                return
            for frame in decoder.feed(data):
                self._handle(frame.message, frame.seq, frame.flags)

    # ------------------------------------------------------------------ behaviour
    def now_us(self) -> int:
        """The agent clock: microseconds since it started (HEARTBEAT uptime_ms is the same clock)."""
        return int((time.monotonic() - self._t0) * 1e6) + 1_000_000

    def send(self, message: Message, flags: int = 0) -> None:
        """Send any frame now (tests inject hostile ones)."""
        self._send(message, flags)

    def send_reordered(self, messages: list[Message], order: list[int]) -> None:
        """Encode `messages` with consecutive seqs, then send them in `order` (indices into `messages`)."""
        with self._lock:
            wires = [self.encoder.encode(message).wire for message in messages]
            if self._conn is not None:
                self._conn.sendall(b"".join(wires[i] for i in order))

    def _send_hello(self) -> None:
        self._send(m.Hello(protocol_version=self.protocol_version, node_kind=1, definitions_hash=self.defs_hash,
                           firmware_major=9, firmware_minor=8, firmware_patch=7, node_id=self.node_id,
                           boot_id=self.boot_id, name=self.name))

    def _handle(self, msg: Message, seq: int, flags: int) -> None:
        if isinstance(msg, m.Hello):  # every ground HELLO is answered (SPEC.md 1.1) and starts a session (1.2)
            self.answered.clear()
            if self.unanswered_hellos > 0:
                self.unanswered_hellos -= 1
            else:
                self._send_hello()
            return
        if isinstance(msg, m.Timesync) and msg.receive_us == 0:
            self.timesync_origins.append(msg.origin_us)
            now = self.now_us()
            if self.lying_timesyncs > 0:
                self.lying_timesyncs -= 1
                now = 2**64 - 1
            self._send(m.Timesync(origin_us=msg.origin_us, receive_us=now, transmit_us=now))
            return
        if not flags & FrameFlag.ACK_REQUESTED:
            return
        if self.ignore_commands > 0:
            self.ignore_commands -= 1
            return
        for mid, s, result in self.answered:
            if (mid, s) == (msg.MSG_ID, seq):
                self._send(m.Ack(cmd_msg_id=mid, cmd_seq=seq, result=result))
                return
        result, after = self._execute(msg)
        self.answered.append((msg.MSG_ID, seq, result))
        if self.drop_before_ack == msg.DEFINITION.name:  # ran, but the link drops before the ACK leaves
            self.drop_before_ack = ""
            self.disconnect()
            return
        self._send(m.Ack(cmd_msg_id=msg.MSG_ID, cmd_seq=seq, result=result, reason=self.nack_reason if result else ""))
        for reply, reply_flags in after:
            self._send(reply, reply_flags)

    def _param(self, index: int, name: str) -> m.ParamValue:
        kind, value, lo, hi = self.params[name]
        return m.ParamValue(index=index, count=len(self.params), param_type=kind, value=value, minimum=lo,
                            maximum=hi, name=name)

    def _execute(self, msg: Message) -> tuple[int, list[tuple[Message, int]]]:
        self.executed.append(msg.DEFINITION.name)
        if self.refuse and not isinstance(msg, m.ParamListRequest | m.LogRequest):
            return self.refuse, []
        names = list(self.params)
        if isinstance(msg, m.ParamListRequest):
            return 0, [(self._param(i, n), 0) for i, n in enumerate(names)]
        if isinstance(msg, m.ParamGet | m.ParamSet):
            name = msg.name if msg.index < 0 else (names[msg.index] if msg.index < len(names) else "")
            if name not in self.params:
                return int(AckResult.BAD_VALUE), []
            if isinstance(msg, m.ParamSet):
                lo, hi = self.params[name][2], self.params[name][3]
                if not lo <= msg.value <= hi:
                    return int(AckResult.BAD_VALUE), []
                self.params[name][1] = msg.value
            return 0, [(self._param(names.index(name), name), 0)]
        if isinstance(msg, m.StartLearning):
            if self.mode_checks and self.learning:
                return int(AckResult.NOT_ALLOWED_IN_MODE), []
            self.learning, self.max_episodes = True, msg.max_episodes + self.episode if msg.max_episodes else 0
            return 0, []
        if isinstance(msg, m.Stop | m.Surface):
            self.learning = False
            return 0, []
        if isinstance(msg, m.DumpRequest):
            data = struct.pack("<101f", *[float(i) for i in range(101)]) if msg.kind == DumpKind.VALUES else bytes(101)
            if msg.dump_id == 0:  # a new snapshot gets a new id, as on the agent (simulator/agent/dumps.py)
                self.last_dump_id += 1
            dump_id = msg.dump_id or self.last_dump_id
            end = len(data) if msg.length == 0 else msg.offset + msg.length
            chunks = [(m.DumpChunk(dump_id=dump_id, kind=msg.kind, episode=self.episode, total_bytes=len(data),
                                   offset=o, data=data[o:min(o + 224, end)]), 0) for o in range(msg.offset, end, 224)]
            if msg.dump_id == 0 and len(chunks) > 1:
                chunks = chunks[:1]  # lose the rest: the ground must ask for the missing range
            return 0, list(chunks)
        if isinstance(msg, m.LogRequest):
            self.log_requests += 1
            replay = [(frame, int(FrameFlag.REPLAYED)) for s, frame in list(self.log)
                      if msg.first_sample <= s < min(msg.end_sample, msg.first_sample + self.replay_limit)]
            if self.ignored_log_requests > 0:
                self.ignored_log_requests -= 1
                replay = []
            rng = m.LogRange(first_sample=0, next_sample=self.sample, replayed=len(replay), bytes_used=0,
                             capacity_bytes=512 * 1024)
            return 0, [*replay, (rng, 0)]
        return 0, []

    def _produce(self) -> None:
        step = 0
        next_hb = time.monotonic()
        while not self._stop.wait(self.period_s):
            if time.monotonic() >= next_hb:
                next_hb += 0.2
                self._send(m.Heartbeat(uptime_ms=self.now_us() // 1000, mode=1 if self.learning else 0,
                                       battery_mv=4000, rx_frames=0, rx_rejects=0, rx_lost=0, log_first_sample=0,
                                       log_next_sample=self.sample,
                                       episode=self.episode, signing_rejects=0))
            if not self.learning:
                continue
            t_us = self.now_us()
            out: list[tuple[int, Message]] = []
            if step == 0:
                self.episode += 1
                out.append((self.sample, m.EpisodeStart(t_us=t_us, episode=self.episode, sample=self.sample,
                                                        start_state=50, depth_m=0.5, velocity_mps=0.0,
                                                        target_depth_m=0.5, z_tol_m=0.1, zdot_tol_mps=0.05,
                                                        p_explore=0.1)))
            out.append((self.sample, m.Sample(t_us=t_us, sample=self.sample, episode=self.episode, step=step,
                                              pressure_pa=106000.0, depth_m=0.5 + self.depth_step_m * step,
                                              velocity_mps=0.01,
                                              actuator_deg=65.0, actuator_cmd_deg=65.0, reward=-1.0, state=50,
                                              action=step % 2, mode=int(Mode.LEARNING))))
            step += 1
            if step == self.episode_len:
                self.successes += self.episode % 2
                out.append((self.sample, m.EpisodeEnd(t_us=t_us, episode=self.episode, sample=self.sample,
                                                      reason=2 if self.episode % 2 else 1, end_state=50, steps=step,
                                                      duration_s=step * 0.1, episode_return=-float(step),
                                                      successes=self.successes)))
                step = 0
                if self.max_episodes and self.episode >= self.max_episodes:
                    self.learning = False
            for index, frame in out:
                self.log.append((index, frame))
                dropped = not self.live or (self.drop_every and isinstance(frame, m.Sample)
                                            and index % self.drop_every == 3)
                if not dropped:
                    self._send(frame)
                    if self.duplicate_frames:
                        self._resend_last()
            self.sample += 1
