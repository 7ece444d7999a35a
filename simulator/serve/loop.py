"""The virtual agent's process loop: one thread, a selector, the program paced in agent time against wall time."""

from __future__ import annotations

import random
import selectors
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from learning import LearnerConfig
from protocol.link_taken import link_taken_notice
from simulator.agent.batch_kernel import SAMPLE_WIRE
from simulator.agent.link import LinkWire
from simulator.agent.mission import Battery, MissionConfig
from simulator.agent.onboard import OnboardAgent, PythonAgent
from simulator.parameters import PlantParams
from simulator.serve.build import ProgramBuild
from simulator.serve.faults import MAX_LOGGED_SEQS, DelayLine, FaultConfig, FrameFaults, frame_seq
from simulator.serve.starting import StartingAgent
from simulator.serve.transport import Pacer, PtyTransport, TcpTransport, Transport

SLICE_S = 0.004  # longest the program runs before the sockets are served again
MAX_WAIT_S = 0.02  # longest select() waits, so pty opens and delayed bytes are noticed
STARTING_WAIT_S = 0.1  # the same while the program builds: frames wake it at once, the build gets the CPU otherwise
ACK_DRAIN_S = 2.0  # a long command effect waits at most this for its ACK to leave (a paced link's queue)
HIGH_WATER_BYTES = 256 * 1024  # real time drops frames above this (a UART FIFO does not wait for a slow reader)
# --speed max runs the program only while the client takes what it sends: a few frames queued at most, so a
# command's ACK is never behind seconds of backlog (flow control from the send side; issue 14).
MAX_SPEED_QUEUE_BYTES = 2 * 1024
STEPS_PER_CLOCK_READ = 8
BATCH_STEPS = 256  # steps of one compiled batch between clock reads at a set speed (well under SLICE_S)
# --firmware: the Python reference, the C firmware's host build, the C firmware on an emulated Cortex-M4
FIRMWARES = ("python", "c", "qemu")


@dataclass(frozen=True)
class ServeConfig:
    """Everything `python -m simulator serve` resolved from its options."""

    plant: PlantParams
    learner: LearnerConfig = field(default_factory=LearnerConfig)
    mission: MissionConfig = field(default_factory=MissionConfig)
    faults: FaultConfig = field(default_factory=FaultConfig)
    host: str = "127.0.0.1"
    port: int = 2323
    pty: bool = False
    speed: float | None = 1.0  # None = as fast as possible
    seed: int | None = None
    key: bytes | None = field(default=None, repr=False)  # signing key: commands must be signed (SPEC s. 12)
    mark_file: Path | None = None  # where the signing mark survives a restart (SPEC s. 12)
    firmware: str = "python"  # the on-board program: python (the reference), c (firmware/ host build)
    baud: int | None = None  # bytes to the ground leave at a UART's rate (10 bits a byte); None = as fast as taken
    build_delay_s: float = 0.0  # for tests ($DIVE_SIM_BUILD_DELAY_S): the program's build takes this much longer


class AgentServer:
    """Owns the transport, the faulty pipe in each direction, the link layer and the on-board program."""

    def __init__(self, config: ServeConfig) -> None:
        self.config = config
        seed = config.seed if config.seed is not None else random.SystemRandom().randrange(2**32)
        rng = np.random.default_rng(seed)
        fault_rng = random.Random(seed ^ 0x5A5A5A5A)
        self.selector = selectors.DefaultSelector()
        self.transport: Transport = (
            PtyTransport(self.selector) if config.pty else TcpTransport(self.selector, config.host, config.port)
        )
        if config.baud is not None:
            self.transport.pacer = Pacer(config.baud)
        faults = config.faults
        self.out_faults = FrameFaults(faults, fault_rng)
        self._out_faulty = faults.active
        self.in_faults = FrameFaults(faults, fault_rng)
        self.out_delay = DelayLine(faults.delay_ms / 1000.0)
        self.in_delay = DelayLine(faults.delay_ms / 1000.0)
        self.dropped_full = 0  # frames dropped because the client did not keep up (real-time speeds)
        self.blacked_out = 0  # frames not sent because the agent was below --blackout-below
        # Per connection: the seq of its first frame, then the seqs lost to faults (for --report).
        self.lost_by_connection: list[list[int]] = []
        self.connection_end_seqs: list[int] = []  # the seq after the last frame of each finished connection
        self._logged = 0
        self._connected_wall_s = 0.0
        node_id = 0x5100_0000 | (seed & 0xFFFF)
        # The Python program is built (its kernels compiled: minutes on a cold cache) while a starting agent answers
        # the link (SPEC s. 4, answer time); the C firmware's host build is made before the address is printed.
        self._build: ProgramBuild[OnboardAgent] | None = None
        self._starting: StartingAgent | None = None
        self.agent: OnboardAgent
        if config.firmware == "python":
            build: ProgramBuild[OnboardAgent] = ProgramBuild(lambda: _onboard_agent(
                config, rng, self._write, node_id, seed, starting.wire), config.build_delay_s)
            starting = StartingAgent(self._write, node_id, Battery().voltage_v, build.progress)
            self._build, self._starting, self.agent = build, starting, starting
        else:
            self.agent = _onboard_agent(config, rng, self._write, node_id, seed)
        self._batches: PythonAgent | None = None  # see _take_over
        self.transport.on_connect = self._connected
        self.transport.on_data = self._received
        self.transport.on_disconnect = self._disconnected
        self.transport.on_replaced = self._replaced_notice
        # True until stop(): a SIGTERM that comes before serve_forever() (the parent killed just as the agent
        # printed its address) must still stop it, so serve_forever() does not set it again.
        self._running = True
        self._next_disconnect_us = self._disconnect_period_us()
        self._ack_wait_until: float | None = None  # see _hold_for_ack
        if self._build is None:
            self._take_over(self.agent)

    @property
    def address(self) -> str:
        return self.transport.address

    # ------------------------------------------------------------------ the faulty link
    def _blacked_out(self) -> bool:
        below = self.config.faults.blackout_below_m
        return below is not None and self.agent.true_depth_m > below

    def _write(self, wire: bytes) -> None:
        transport = self.transport
        if not transport.connected:
            return
        if self._blacked_out():
            self.blacked_out += 1
            self._log_lost(wire)
            return
        if self._out_faulty:  # skipped per frame when no drop or corruption was asked for
            sent = self.out_faults.frame(wire)
            if sent != wire:
                self._log_lost(wire)
            wire = sent
            if not wire:
                return
        if self.out_delay.delay_s:
            self.out_delay.put(time.monotonic(), wire)
        elif self.config.speed is not None and len(transport.outbuf) > HIGH_WATER_BYTES:
            # Like a UART FIFO: the agent does not wait for a slow reader. Each frame lost (a batch writes several)
            # is logged as a fault's is: the ground sees it as a seq gap.
            for frame in wire.split(b"\x00")[:-1]:
                self.dropped_full += 1
                self._log_lost(frame + b"\x00")
        else:
            transport.outbuf += wire

    def _received(self, data: bytes) -> None:
        if self._blacked_out():
            return
        data = self.in_faults.stream(data)
        if not data:
            return
        if self.in_delay.delay_s:
            self.in_delay.put(time.monotonic(), data)
        else:
            self.agent.receive(data)

    def _log_lost(self, wire: bytes) -> None:
        seq = frame_seq(wire)
        if seq is not None and self.lost_by_connection and self._logged < MAX_LOGGED_SEQS:
            self._logged += 1
            self.lost_by_connection[-1].append(seq)

    def _disconnected(self) -> None:
        self.connection_end_seqs.append(self.agent.next_seq)
        self.agent.link_down()

    def _replaced_notice(self) -> bytes:
        """The notice for a connection a new one replaces (SPEC.md s. 4), with a seq of its own: the old link ends."""
        return link_taken_notice(self.agent.t_us)

    def _connected(self) -> None:
        self._connected_wall_s = time.monotonic()
        self.lost_by_connection.append([self.agent.next_seq])
        self.in_faults.reset()
        self.out_delay.clear()
        self.in_delay.clear()
        self._next_disconnect_us = self.agent.t_us + self._disconnect_period_us()
        self.agent.link_up()

    def _disconnect_period_us(self) -> int:
        every_s = self.config.faults.disconnect_every_s
        return int(every_s * 1e6) if every_s else 2**63

    def report(self) -> dict[str, object]:
        """What the faults did and what the agent produced (serve --report FILE writes it at exit)."""
        out, into, agent = self.out_faults, self.in_faults, self.agent
        counters = agent.counters()
        ends = [*self.connection_end_seqs, agent.next_seq][: len(self.lost_by_connection)]
        return {
            "connections": len(self.lost_by_connection), "next_sample": counters["next_sample"],
            "t_agent_s": agent.t_us / 1e6, "signing_rejects": counters["signing_rejects"],
            "out": {"dropped": out.dropped, "corrupted": out.corrupted, "blacked_out": self.blacked_out,
                    "dropped_full": self.dropped_full, "lost_by_connection": self.lost_by_connection,
                    "connection_end_seqs": ends},
            "in": {"dropped": into.dropped, "corrupted": into.corrupted, "rx_lost": counters["rx_lost"],
                   "rx_rejects": counters["rx_rejects"]},
        }

    # ------------------------------------------------------------------ the loop
    def stop(self) -> None:
        self._running = False

    def serve_forever(self) -> None:
        """Run until stop() (a signal handler calls it, maybe before this starts); always closes the port."""
        try:
            if self._build is not None:
                self._start_program(self._build)
            self._loop()
        finally:
            self.close()

    def _start_program(self, build: ProgramBuild[OnboardAgent]) -> None:
        """The link served by the starting agent while the program builds; then the program takes over."""
        build.start()
        while self._running and not build.done:
            self._io(STARTING_WAIT_S, eager=False)
        if not self._running:
            return  # stopped while building: the daemon thread ends with the process
        program = build.result()  # the build's own error ends the server (serve/cli.py: one line, exit 1)
        assert self._starting is not None
        self._starting.built()
        self.agent = program
        if isinstance(program, PythonAgent):
            program.take_over()
        self._take_over(program)

    def _take_over(self, agent: OnboardAgent) -> None:
        """Compiled batches of steps (onboard_batch.py) where nothing acts per frame or per step: with faults, each
        frame is dropped, corrupted, delayed or blacked out on its own, and a disconnect falls between two steps."""
        faults = self.config.faults
        if isinstance(agent, PythonAgent) and not (
            faults.active or faults.delay_ms or faults.disconnect_every_s or faults.blackout_below_m is not None
        ):
            self._batches = agent

    def close(self) -> None:
        try:
            self.transport.close()
        finally:
            self.selector.close()

    def _loop(self) -> None:
        speed = self.config.speed
        agent, transport = self.agent, self.transport
        wall0 = time.monotonic()
        agent0_us = agent.t_us
        while self._running:
            now = time.monotonic()
            if speed is None:
                due_us = 2**63
                # "As fast as the client reads" includes no client: agent time stands still until one connects,
                # so a reconnect does not cost thousands of agent seconds nobody received (benchmarks/soak.py).
                blocked = len(transport.outbuf) > MAX_SPEED_QUEUE_BYTES or not transport.connected
            else:
                due_us = agent0_us + int((now - wall0) * speed * 1e6)
                blocked = False
            if agent.work_after_ack:
                blocked = self._hold_for_ack(now) or blocked
            deadline = now + SLICE_S
            steps = 0
            if self._batches is not None and not blocked:
                steps = self._run_batches(speed, due_us, deadline)
                blocked = True  # the batches ran to the slice's end or the queue's limit
            while not blocked and agent.t_us < due_us:
                agent.step()
                steps += 1
                if agent.t_us >= self._next_disconnect_us and \
                        time.monotonic() - self._connected_wall_s >= self.config.faults.min_connection_s:
                    self._next_disconnect_us = agent.t_us + self._disconnect_period_us()
                    transport.drop_client()
                if steps % STEPS_PER_CLOCK_READ == 0:
                    if time.monotonic() >= deadline:
                        break
                    if speed is None and len(transport.outbuf) > MAX_SPEED_QUEUE_BYTES:
                        break
            if speed is not None and agent.t_us < due_us and steps and time.monotonic() >= deadline:
                # Cannot keep up with the requested speed: do not try to catch up in a burst later.
                wall0, agent0_us = time.monotonic(), agent.t_us
            self._io(self._wait_s(speed, due_us))

    def _hold_for_ack(self, now: float) -> bool:
        """True while a command's ACK is still queued and the command's long effect (a learner restart, seconds of
        compiling on a cold cache) must wait for it (SPEC s. 5: the ACK comes first); then runs the effect."""
        if self._ack_wait_until is None:
            self._ack_wait_until = now + ACK_DRAIN_S
        if self.transport.outbuf and self.transport.connected and now < self._ack_wait_until:
            return True
        self._ack_wait_until = None
        self.agent.finish_command()
        return False

    def _run_batches(self, speed: float | None, due_us: int, deadline: float) -> int:
        """Compiled batches of steps until the slice ends, agent time is due or (--speed max) the queue is full.

        At --speed max a batch is sized to the room left in the out buffer and flushed at once, so the queue to
        the client never holds more than MAX_SPEED_QUEUE_BYTES and a SAMPLE of frames.
        """
        agent, transport = self._batches, self.transport
        assert agent is not None
        steps = 0
        while agent.t_us < due_us:
            if speed is None:
                room = MAX_SPEED_QUEUE_BYTES - len(transport.outbuf)
                if room < 0 or not transport.connected:
                    break
                steps += agent.run(room // SAMPLE_WIRE + 1, due_us)
                transport.flush()
            else:
                steps += agent.run(BATCH_STEPS, due_us)
            if time.monotonic() >= deadline:
                break
        return steps

    def _wait_s(self, speed: float | None, due_us: int) -> float:
        if speed is None:
            held = len(self.transport.outbuf) > MAX_SPEED_QUEUE_BYTES or not self.transport.connected
            wait = MAX_WAIT_S if held else 0.0
        else:
            # Sleep until the next control step is due in agent time.
            wait = min(MAX_WAIT_S, max(0.0, (self.agent.t_us + 1 - due_us) / 1e6 / speed))
        pacer, pending = self.transport.pacer, len(self.transport.outbuf)
        if pacer is not None and pending and self.transport.connected:
            wait = min(wait, pacer.wait_s(pending))  # the UART takes more bytes then
        for line in (self.out_delay, self.in_delay):
            release = line.next_release_s()
            if release is not None:
                wait = min(wait, max(0.0, release - time.monotonic()))
        return wait

    def _io(self, timeout_s: float, eager: bool = True) -> None:
        """Serve the link for up to timeout_s; `eager` (a program that runs at --speed max): back at once once the
        flush made room."""
        transport = self.transport
        transport.poll()
        self.agent.service()
        transport.flush()
        if eager and self.config.speed is None and timeout_s and transport.connected and \
                len(transport.outbuf) <= MAX_SPEED_QUEUE_BYTES:
            timeout_s = 0.0  # the flush made room: the program runs again at once (only reads are waited for)
        for key, mask in self.selector.select(timeout_s):
            key.data(mask)
        now = time.monotonic()
        if len(self.out_delay):
            ready = self.out_delay.due(now)
            if ready and transport.connected:
                transport.outbuf += ready
        if len(self.in_delay):
            ready = self.in_delay.due(now)
            if ready:
                self.agent.receive(ready)
        transport.flush()


def _onboard_agent(config: ServeConfig, rng: np.random.Generator, write: Callable[[bytes], None], node_id: int,
                   seed: int, wire: LinkWire | None = None) -> OnboardAgent:
    """The on-board program the configuration names: the Python reference, or the C firmware's host build.

    SPEC s. 4, time base: faster than real time, link silence, the HELLO repeat and signing ages are in wall
    seconds, because the ground lives in wall time; otherwise in agent time, as on the real agent.
    """
    fast = config.speed is None or config.speed > 1.0
    if config.firmware == "c":
        from simulator.serve.firmware_host import FirmwareAgent  # builds or loads the C library only when asked for

        # The firmware keeps its non-volatile area (the signing mark) in its own format, beside the Python agent's.
        nv_file = config.mark_file.with_name(config.mark_file.name + ".fw-nv") if config.mark_file else None
        return FirmwareAgent(config.plant, rng, write, node_id, config.key, seed, wall_link_clock=fast,
                             nv_file=nv_file)
    return PythonAgent(config.plant, config.learner, config.mission, rng, write, node_id, config.key,
                       link_clock_s=time.monotonic if fast else None, mark_file=config.mark_file, wire=wire)
