"""Ground-station speed: frames/s through decode + record vs the mcap writer alone; command RTT vs a raw echo.

Run: .venv/bin/python benchmarks/groundstation_bench.py
"""

from __future__ import annotations

import socket
import statistics
import tempfile
import threading
import time
from pathlib import Path

from groundstation.events import Received
from groundstation.links import open_link
from groundstation.mcap_io import McapFileWriter
from groundstation.recorder import Recorder, RecorderConfig, message_json, message_schema
from groundstation.session import Session, SessionConfig
from groundstation.stats import percentile
from protocol import StreamDecoder
from protocol import messages as m

CAPTURE_S = 6.0


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
    recorder = Recorder(RecorderConfig(directory=directory, flush_period_s=1.0))
    decoder = StreamDecoder()
    start = time.perf_counter()
    frames = 0
    for i in range(0, len(wire), 4096):
        for frame in decoder.feed(wire[i:i + 4096]):
            if frames == 0:
                recorder._hello = {"name": "bench"}
                recorder._open()
            recorder.on_received(Received(frame, time.time_ns(), None, False))
            frames += 1
    recorder.close()
    return time.perf_counter() - start, frames


def writer_alone(wire: bytes, path: Path) -> tuple[float, int]:
    frames = StreamDecoder().feed(wire)
    bodies = [(f.message, message_json(f.message, f.seq, f.flags, False), f.inner) for f in frames]
    start = time.perf_counter()
    with McapFileWriter(path) as w:
        for message, body, inner in bodies:
            name = message.DEFINITION.name
            now = time.time_ns()
            w.write(w.channel(f"/agent/{name}", "json", f"diving_agent.{name}", message_schema(type(message))),
                    body, now)
            w.write(w.channel("/raw/rx", "diving-agent-frame-v1"), inner, now)
    return time.perf_counter() - start, len(bodies)


def command_rtts(n: int = 300) -> list[float]:
    with Session(open_link("sim://?speed=1&seed=1"), SessionConfig(fetch_params=False)) as s:
        rtts = []
        for _ in range(n):
            t = time.perf_counter()
            s.command(m.ParamGet(index=0, name=""))
            rtts.append(time.perf_counter() - t)
    return rtts


def echo_rtts(n: int = 300) -> list[float]:
    server = socket.create_server(("127.0.0.1", 0))

    def serve() -> None:
        conn, _ = server.accept()
        with conn:
            while data := conn.recv(256):
                conn.sendall(data)

    threading.Thread(target=serve, daemon=True).start()
    client = socket.create_connection(server.getsockname())
    client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    payload = bytes(range(1, 20)) + b"\x00"
    rtts = []
    for _ in range(n):
        t = time.perf_counter()
        client.sendall(payload)
        got = b""
        while len(got) < len(payload):
            got += client.recv(256)
        rtts.append(time.perf_counter() - t)
    client.close()
    server.close()
    return rtts


def main() -> None:
    wire = capture_wire(CAPTURE_S)
    with tempfile.TemporaryDirectory() as tmp:
        full_s, frames = decode_and_record(wire, Path(tmp))
        alone_s, frames_alone = writer_alone(wire, Path(tmp) / "alone.mcap")
    full_fps, alone_fps = frames / full_s, frames_alone / alone_s
    print(f"captured {len(wire)} bytes, {frames} frames from the virtual agent at --speed max in {CAPTURE_S:g} s "
          f"({frames / CAPTURE_S:,.0f} frames/s offered)")
    print(f"decode + record (StreamDecoder + Recorder):  {full_fps:12,.0f} frames/s")
    print(f"mcap writer alone, same messages:            {alone_fps:12,.0f} frames/s")
    print(f"ratio decode+record / writer alone:          {full_fps / alone_fps:12.2f}")
    cmd, echo = command_rtts(), echo_rtts()
    for name, values in (("command round trip (PARAM_GET -> ACK)", cmd), ("raw socket echo", echo)):
        print(f"{name:40s} median {statistics.median(values) * 1e3:7.3f} ms   "
              f"p95 {percentile(values, 0.95) * 1e3:7.3f} ms")
    print(f"ratio command / echo: median {statistics.median(cmd) / statistics.median(echo):.1f}x, "
          f"p95 {percentile(cmd, 0.95) / percentile(echo, 0.95):.1f}x")


if __name__ == "__main__":
    main()
