"""The emulated agent's link: at speed max the board runs only as fast as its ground reads; --pty serves it too.

Issue 30's bug: the kernel's TCP buffers between QEMU, the relay and the ground grew to over a megabyte on
loopback (ten minutes of agent time), so a ground slowed by a loaded machine saw the agent late and commanded it
late, and `dive fit --excite` overran the agent's max_dive_s.
"""

from __future__ import annotations

import os
import select
import shutil
import socket
import time
import tty

import pytest

from groundstation.links.tcp import RECEIVE_BUFFER_BYTES
from protocol import FrameEncoder, FrameFlag, StreamDecoder, messages
from simulator.serve.firmware_qemu import UART_BUFFER_BYTES, QemuAgent, QemuConfig, build_elf
from simulator.serve.qemu_relay import BURST_MAX_BYTES
from simulator.serve.transport import UNSENT_BYTES

PAUSE_S = 1.5
# What may wait between the firmware and a ground that stopped reading (Linux doubles each buffer): QEMU's UART
# socket and ours, the relay's unsent bytes and one burst in its hands, the ground's receive buffer. Before the fix,
# a 1.5 s pause piled up 180 kB, and over a megabyte given longer (~1 kB is one agent second hovering).
MAY_WAIT_BYTES = 2 * (2 * UART_BUFFER_BYTES + UNSENT_BYTES + RECEIVE_BUFFER_BYTES) + BURST_MAX_BYTES


def _read(sock: socket.socket, decoder: StreamDecoder, seconds: float, latest: int) -> tuple[int, int]:
    """Read for `seconds` (0: only what is there now); (the newest SAMPLE time seen, the bytes read)."""
    deadline = time.monotonic() + seconds
    count = 0
    while True:
        ready, _, _ = select.select([sock], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            return latest, count
        data = sock.recv(65536)
        assert data, "the relay closed the link"
        count += len(data)
        for frame in decoder.feed(data):
            if isinstance(frame.message, messages.Sample):
                latest = frame.message.t_us
        if seconds and time.monotonic() >= deadline:
            return latest, count


def test_agent_waits_for_a_ground_that_stops_reading() -> None:
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not found: the QEMU tests need it")
    with QemuAgent(QemuConfig(seed=5), build_elf()) as agent:
        host, port = agent.address.removeprefix("tcp://").rsplit(":", 1)
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, RECEIVE_BUFFER_BYTES)  # as the ground's link does
        sock.connect((host, int(port)))
        with sock:
            decoder = StreamDecoder()
            sock.sendall(FrameEncoder().encode(messages.Hover(depth_m=0.5), int(FrameFlag.ACK_REQUESTED)).wire)
            t0, _ = _read(sock, decoder, 0.5, -1)
            t1, read = _read(sock, decoder, PAUSE_S, t0)  # the ground reads
            t1, _ = _read(sock, decoder, 0.0, t1)
            time.sleep(PAUSE_S)  # the ground stalls (a loaded machine)
            t2, piled = _read(sock, decoder, 0.0, t1)  # all that waited meanwhile
    assert t1 > t0 >= 0 and read > 0, "no SAMPLE while hovering"
    assert piled <= MAY_WAIT_BYTES, f"{piled} bytes ({(t2 - t1) / 1e6:.1f} agent s) piled up in a {PAUSE_S:g} s " \
                                    f"pause ({read} bytes, {(t1 - t0) / 1e6:.1f} agent s while reading)"


def test_pty_link_serves_the_board() -> None:
    """--pty: QEMU's own pseudo-terminal is the link (QEMU 7 names it on stdout, which was not read)."""
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not found: the QEMU tests need it")
    with QemuAgent(QemuConfig(seed=5, pty=True), build_elf()) as agent:
        assert agent.address.startswith("/dev/")
        fd = os.open(agent.address, os.O_RDWR | os.O_NOCTTY)
        try:
            tty.setraw(fd)
            decoder = StreamDecoder()
            found: list[object] = []
            deadline = time.monotonic() + 10.0
            while not any(isinstance(x, messages.Hello) for x in found) and time.monotonic() < deadline:
                if select.select([fd], [], [], 0.2)[0]:
                    found += [frame.message for frame in decoder.feed(os.read(fd, 4096))]
        finally:
            os.close(fd)
    assert any(isinstance(x, messages.Hello) for x in found), f"no HELLO in {len(found)} frames"
