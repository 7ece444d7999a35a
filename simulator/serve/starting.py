"""The agent while its program builds (SPEC.md s. 4, *A starting agent*): HELLO, TIMESYNC, HEARTBEAT, BUSY for commands.

A virtual agent compiles its kernels before its program can run: seconds from a warm cache, minutes from a cold one
on a loaded machine. Meanwhile this answers the link within SPEC's 1 s bound, truthfully: the HELLO the program
will send (same node_id, boot_id and generation), agent time still 0 (the clock starts with the program), every
command NACKed BUSY (nothing run, nothing remembered), and a TEXT now and then saying how far the build got. The
program then takes over its frame counter, its receive side and the link's state (agent/link.py's LinkWire), so no
frame is lost, sent twice or numbered out of turn.
"""

from __future__ import annotations

import time
from collections.abc import Callable

from protocol import AckResult, FrameEncoder, Severity, StreamDecoder, messages
from protocol.decoder import COMMAND_IDS_FROM
from protocol.registry import Message
from simulator.agent.identity import FIRST_GENERATION, HELLO_REPEAT_S, agent_hello
from simulator.agent.link import LinkWire
from simulator.serve.build import BuildProgress

HEARTBEAT_PERIOD_S = 1.0  # of link time: agent time stands still until the program runs (SPEC s. 4)
PROGRESS_TEXT_S = 5.0  # a TEXT on how far the build got, this often
TEXT_BYTES = 200  # a TEXT's line and an ACK's reason hold more; a kernel's long name must not cut the frame


def _line(text: str) -> str:
    return text.encode()[:TEXT_BYTES].decode(errors="ignore")


class StartingAgent:
    """Stands in for the OnboardAgent (serve/onboard.py) while the program builds; no step ever runs."""

    def __init__(self, write: Callable[[bytes], None], node_id: int, battery_v: float, progress: BuildProgress,
                 clock_s: Callable[[], float] = time.monotonic) -> None:
        self.write = write
        self.node_id = node_id
        self.battery_mv = int(battery_v * 1000)
        self.progress = progress
        # The program's link carries on with it (PythonAgent's `wire`). No compiled codec meanwhile: loading it starts
        # a compile of its own (10.7 s on a cold cache at load 12) that would hold the program's build up, for the
        # few frames a starting agent sends; the program turns it on (AgentLink.take_over).
        self.wire = LinkWire(FrameEncoder(compiled=False), StreamDecoder(agent=True, compiled=False))
        self._clock_s = clock_s
        self._next_hello_s = 0.0
        self._next_heartbeat_s = 0.0
        self._next_text_s = 0.0
        self.busy_answers = 0

    # ------------------------------------------------------------------ what the server reads
    @property
    def t_us(self) -> int:
        return 0  # the program's clock has not started

    @property
    def next_seq(self) -> int:
        return self.wire.encoder.next_seq

    @property
    def true_depth_m(self) -> float:
        return 0.0  # at the surface, where it boots

    @property
    def work_after_ack(self) -> bool:
        return False

    def finish_command(self) -> None:
        """Nothing runs after a BUSY."""

    def step(self) -> None:
        raise RuntimeError("the program is not built yet: the server steps it only after the hand-over")

    def counters(self) -> dict[str, int]:
        stats = self.wire.decoder.stats
        return {"next_sample": 0, "signing_rejects": 0, "rx_lost": stats.lost, "rx_rejects": stats.rejects}

    # ------------------------------------------------------------------ the link
    def link_up(self) -> None:
        """A new connection: sequence tracking starts over, HELLO, and a TEXT saying why commands wait."""
        self.wire.decoder.reset_sequence()
        self.wire.connected, self.wire.heard = True, False
        self._hello()
        self._text()

    def link_down(self) -> None:
        self.wire.connected = False

    def receive(self, data: bytes) -> None:
        for frame in self.wire.decoder.feed(data):
            self.wire.heard = True
            message = frame.message
            if frame.msg_id >= COMMAND_IDS_FROM:
                # Before any other check (SPEC s. 5): nothing can run yet, so nothing is remembered or counted.
                self.busy_answers += 1
                reason = _line(f"starting, {self.progress.describe()}: try again later")
                self._send_payload(messages.Ack.MSG_ID, messages.Ack.pack_values(
                    frame.msg_id, frame.seq, int(AckResult.BUSY), reason))
            elif isinstance(message, messages.Hello):
                self._hello()
            elif isinstance(message, messages.Timesync) and message.receive_us == 0 and message.transmit_us == 0:
                # The clock reads 0 until the program runs: receive_us 0, transmit_us 1 (a reply is never 0).
                self._send(messages.Timesync(origin_us=message.origin_us, receive_us=0, transmit_us=1))

    def service(self) -> None:
        """Every loop of the server: the HELLO repeat, HEARTBEAT and the build's progress in a TEXT."""
        if not self.wire.connected:
            return
        now = self._clock_s()
        if not self.wire.heard and now >= self._next_hello_s:
            self._hello()
        if now >= self._next_heartbeat_s:
            self._next_heartbeat_s = now + HEARTBEAT_PERIOD_S
            stats = self.wire.decoder.stats
            self._send(messages.Heartbeat(
                uptime_ms=0, mode=0, battery_mv=self.battery_mv, rx_frames=stats.frames, rx_rejects=stats.rejects,
                rx_lost=stats.lost, log_first_sample=0, log_next_sample=0, episode=0, signing_rejects=0,
                generation=FIRST_GENERATION))
        if now >= self._next_text_s:
            self._text()

    def built(self) -> None:
        """The program runs from now on: the last word of the starting agent."""
        if self.wire.connected:
            self._send(messages.Text(t_us=0, severity=int(Severity.INFO),
                                     text=f"program built in {self.progress.elapsed_s():.1f} s "
                                          f"({self.progress.compiled} kernels compiled): commands run now"))

    def _hello(self) -> None:
        self._next_hello_s = self._clock_s() + HELLO_REPEAT_S
        self._send(agent_hello(self.node_id, self.wire.boot_id, FIRST_GENERATION))

    def _text(self) -> None:
        self._next_text_s = self._clock_s() + PROGRESS_TEXT_S
        self._send(messages.Text(t_us=0, severity=int(Severity.INFO), text=_line(
            f"starting, {self.progress.describe()}: commands are answered BUSY until it runs")))

    def _send(self, message: Message) -> None:
        self._send_payload(message.MSG_ID, message.pack())

    def _send_payload(self, msg_id: int, payload: bytes) -> None:
        self.write(self.wire.encoder.encode_payload(msg_id, payload).wire)
