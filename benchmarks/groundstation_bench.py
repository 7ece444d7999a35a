"""Ground-station speed: frames/s through decode + record vs the mcap writer alone; command RTT vs a raw echo.

Command round trip: PARAM_GET -> ACK through a Session to the virtual agent (`sim://?speed=1`: idle, stepping in
real time), against a 20-byte frame echoed by another process and received by a reader thread. The agent's
reply time seen by a bare client (no session) is printed too, to show which side the time is on. The same is
measured against the robot's own program, the C firmware's host build (`sim://?firmware=c`), when it builds here.
Commands and echoes take turns, so both meet the same machine, in two conditions: back to back, and each after
1 ms of idleness (see CONDITIONS).

Run: .venv/bin/python benchmarks/groundstation_bench.py
"""

from __future__ import annotations

import gc
import json
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, fields
from pathlib import Path

from mcap.writer import CompressionType, Writer

from groundstation.links import open_link
from groundstation.links.sim import SimLink
from groundstation.recording.bodies import message_json
from groundstation.recording.recorder import Recorder, RecorderConfig, message_schema
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import Received
from groundstation.session.stats import percentile
from protocol import FrameEncoder, StreamDecoder, compiled
from protocol import messages as m
from simulator.serve.firmware_host import FirmwareBuildError, library_path

CAPTURE_S = 6.0
ROUNDS = 3
ROUND_TRIP_ROUNDS = 5
ROUND_TRIPS = 300  # of each kind, per condition and round
# How long the machine idles before each round trip. Back to back, the next one comes within ~0.2 ms; from idle,
# after 1 ms, as a command a person types does. On this VM the ratio depends on it (each wake-up a halt exit).
CONDITIONS = {"back to back": 0.0, "from idle": 0.001}
AGENTS = {"python": "the Python virtual agent (sim://)",
          "c": "the robot's own program, the C firmware's host build (sim://?firmware=c)"}


def capture_wire(seconds: float) -> bytes:
    """Raw bytes from a virtual agent at --speed max while it learns."""
    chunks: list[bytes] = []
    link = open_link("sim://?speed=max&seed=1")
    try:
        s = Session(link, SessionConfig(reconnect=False, fetch_params=False))
        s.connect()
        s.command(m.StartLearning(max_episodes=0))
        s._stop.set()  # stop the reader: read the raw stream ourselves
        if s._thread is not None:
            s._thread.join(2)
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            chunks.append(link.recv(0.1))
    finally:
        link.close()
    return b"".join(chunks)


def decode_and_record(wire: bytes, directory: Path) -> tuple[float, int]:
    """StreamDecoder + Recorder on the captured stream in 4 KiB reads; the file is opened before the clock starts."""
    recorder = Recorder(RecorderConfig(directory=directory, flush_period_s=1.0))
    recorder._hello = {"name": "bench"}
    recorder._open()
    decoder = StreamDecoder()
    start = time.process_time()
    frames = 0
    for i in range(0, len(wire), 4096):
        for frame in decoder.feed(wire[i:i + 4096]):
            recorder.on_received(Received(frame, time.time_ns(), None, False))
            frames += 1
    recorder.close()
    return time.process_time() - start, frames


def writer_alone(wire: bytes, path: Path) -> tuple[float, int]:
    """The anchor: the mcap library's Writer alone, as a best-case writer would use it.

    Bodies are encoded and channels registered before the clock starts; only the two add_message calls
    per frame (the JSON body and the raw frame, as the recorder writes) and finishing the file are timed.
    """
    frames = StreamDecoder().feed(wire)
    with open(path, "wb") as stream:
        writer = Writer(stream, chunk_size=256 * 1024, compression=CompressionType.ZSTD)
        writer.start(profile="diving-agent", library="bench")
        channels: dict[str, int] = {}
        for frame in frames:
            name = frame.message.DEFINITION.name
            if name not in channels:
                schema = writer.register_schema(f"diving_agent.{name}", "jsonschema",
                                                json.dumps(message_schema(type(frame.message))).encode())
                channels[name] = writer.register_channel(f"/agent/{name}", "json", schema)
        raw = writer.register_channel("/raw/rx", "diving-agent-frame-v1", 0)
        bodies = [(channels[f.message.DEFINITION.name], message_json(f.message, f.seq, f.flags, False), f.inner)
                  for f in frames]
        start = time.process_time()
        for channel, body, inner in bodies:
            now = time.time_ns()
            writer.add_message(channel, log_time=now, data=body, publish_time=now)
            writer.add_message(raw, log_time=now, data=inner, publish_time=now)
        writer.finish()
    return time.process_time() - start, len(bodies)


@contextmanager
def echo_round_trip() -> Iterator[Callable[[], float]]:
    """The anchor: a 20-byte frame echoed by another process over loopback, received by a reader thread.

    The shape of a command round trip without our code: the main thread sends and waits on an event,
    a reader thread blocked in recv() gets the echo and sets the event (as Session's reader sets an ACK's).
    Yields a function that makes one round trip and returns its seconds.
    """
    server = subprocess.Popen([sys.executable, "-c", ECHO_SERVER], stdout=subprocess.PIPE, text=True)
    try:
        assert server.stdout is not None
        client = socket.create_connection(("127.0.0.1", int(server.stdout.readline())))
        client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        payload = bytes(range(1, 20)) + b"\x00"
        arrived = threading.Event()

        def read() -> None:
            got = b""
            while data := client.recv(4096):
                got += data
                while b"\x00" in got:
                    _, got = got.split(b"\x00", 1)
                    arrived.set()

        def round_trip() -> float:
            arrived.clear()
            t = time.perf_counter()
            client.sendall(payload)
            arrived.wait(5.0)
            return time.perf_counter() - t

        reader = threading.Thread(target=read, daemon=True)
        reader.start()
        yield round_trip
        client.shutdown(socket.SHUT_RDWR)
        reader.join(2)
        client.close()
    finally:
        server.kill()
        server.wait()


@contextmanager
def bare_round_trip(url: str) -> Iterator[Callable[[], float]]:
    """PARAM_GET -> ACK on a plain socket, read in the sending thread: the agent's own reply time (no session, no
    reader thread), for the breakdown. Yields a function that makes one round trip and returns its seconds."""
    host, port = url.removeprefix("tcp://").rsplit(":", 1)
    encoder, decoder = FrameEncoder(), StreamDecoder()
    with socket.create_connection((host, int(port))) as sock:
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

        def round_trip() -> float:
            wire = encoder.encode(m.ParamGet(index=0, name="")).wire
            t = time.perf_counter()
            sock.sendall(wire)
            while not any(isinstance(f.message, m.Ack) for f in decoder.feed(sock.recv(65536))):
                pass
            return time.perf_counter() - t

        yield round_trip


def paired(first: Callable[[], float], second: Callable[[], float], idle_s: float,
           n: int = ROUND_TRIPS) -> tuple[list[float], list[float]]:
    """n round trips of each, in turn, each after idle_s of idleness: the two meet the same state of the machine
    (run one after the other, the echoes came 70 us apart and met a machine the commands did not)."""
    a: list[float] = []
    b: list[float] = []
    for _ in range(n):
        if idle_s:
            time.sleep(idle_s)
        a.append(first())
        if idle_s:
            time.sleep(idle_s)
        b.append(second())
    return a, b


@dataclass
class Paired:
    """One condition's round trips: the session's commands and the bare client's, each with its own echoes."""

    command: list[float] = field(default_factory=list)
    echo: list[float] = field(default_factory=list)
    bare: list[float] = field(default_factory=list)
    bare_echo: list[float] = field(default_factory=list)

    def add(self, other: Paired) -> None:
        for kind in fields(self):
            getattr(self, kind.name).extend(getattr(other, kind.name))


def agent_round(firmware: str) -> dict[str, Paired]:
    """PARAM_GET -> ACK through a Session to the virtual agent at --speed 1 (idle, stepping in real time as a
    diving agent does), then from a bare client on the same agent, each paired with echoes, in every condition."""
    results = {name: Paired() for name in CONDITIONS}
    link = open_link(f"sim://?speed=1&seed=1&firmware={firmware}")
    with Session(link, SessionConfig(fetch_params=False, reconnect=False)) as s, echo_round_trip() as echo:

        def command() -> float:
            t = time.perf_counter()
            s.command(m.ParamGet(index=0, name=""))
            return time.perf_counter() - t

        for name, idle_s in CONDITIONS.items():
            results[name].command, results[name].echo = paired(command, echo, idle_s)
        assert isinstance(link, SimLink) and link.agent_url is not None
        # the agent serves one client: this connection replaces the session's
        with bare_round_trip(link.agent_url) as bare:
            for name, idle_s in CONDITIONS.items():
                results[name].bare, results[name].bare_echo = paired(bare, echo, idle_s)
    return results


ECHO_SERVER = """
import socket, sys
server = socket.create_server(("127.0.0.1", 0))
print(server.getsockname()[1], flush=True)
conn, _ = server.accept()
conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
while data := conn.recv(4096):
    conn.sendall(data)
"""


def record_speed() -> None:
    """Decode + record against the mcap writer alone, rounds in turn, on a stream captured once."""
    wire = capture_wire(CAPTURE_S)
    ratios: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        print(f"captured {len(wire)} bytes from the virtual agent at --speed max in {CAPTURE_S:g} s")
        for round_ in range(ROUNDS):  # in turn, so a change of load falls on both
            full_s, frames = decode_and_record(wire, Path(tmp) / str(round_))
            alone_s, frames_alone = writer_alone(wire, Path(tmp) / f"alone{round_}.mcap")
            full_fps, alone_fps = frames / full_s, frames_alone / alone_s
            ratios.append(full_fps / alone_fps)
            print(f"round {round_ + 1}: decode + record (StreamDecoder + Recorder) {full_fps:10,.0f} frames/s; "
                  f"mcap Writer alone, same frames {alone_fps:10,.0f} frames/s; ratio {ratios[-1]:.2f}")
    print(f"ratio decode+record / writer alone: median {statistics.median(ratios):.2f} of {ROUNDS} (goal >= 1.0)")


def round_trips(firmware: str) -> None:
    """Command round trips to the agent running `firmware` against the echo anchor, in each condition."""
    # Each round has a fresh agent and echo server: the scheduler places the three threads of a round trip anew each
    # round, and one round's ratio swung 1.3-4x with where they landed (two idle cores of a VM, each wake-up a halt
    # exit). Each round's ratios, then medians over all round trips.
    print(f"agent: {AGENTS[firmware]}")
    totals = {name: Paired() for name in CONDITIONS}
    for round_ in range(ROUND_TRIP_ROUNDS):
        results = agent_round(firmware)
        ratios = [f"{name} {statistics.median(r.command) / statistics.median(r.echo):.2f}"
                  for name, r in results.items()]
        print(f"round {round_ + 1}: command / echo: {'; '.join(ratios)}")
        for name, r in results.items():
            totals[name].add(r)
    for name, r in totals.items():
        command, echo = statistics.median(r.command), statistics.median(r.echo)
        # No session answers faster than its agent: the agent's reply alone (against its own echoes) bounds it.
        print(f"{name + ':':14s} command {command * 1e3:.3f} ms (p95 {percentile(r.command, 0.95) * 1e3:.3f}), echo "
              f"{echo * 1e3:.3f} ms (p95 {percentile(r.echo, 0.95) * 1e3:.3f}); the agent's reply alone "
              f"{statistics.median(r.bare) / statistics.median(r.bare_echo):.2f}x its echo")
        print(f"ratio command / echo ({firmware}, {name}): median {command / echo:.2f}x (goal <= 2), "
              f"p95 {percentile(r.command, 0.95) / percentile(r.echo, 0.95):.2f}x")


def main() -> None:
    compiled.wait()  # the compiled decoder loads in the background: measure it loaded
    record_speed()
    # The captured stream (~120 MB) and what decoding it left are gone before the round trips are timed: a ground
    # station holds no such heap, and the collector walking it inflated round trips at random (0.14-0.25 ms).
    gc.collect()
    round_trips("python")
    try:
        library_path()  # builds the C firmware's host library, or says why it cannot
    except FirmwareBuildError as e:
        print(f"agent: {AGENTS['c']}: not measured: {e}")
        return
    round_trips("c")


if __name__ == "__main__":
    main()
