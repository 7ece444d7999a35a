"""A tiny ground-station stand-in for tests: a raw socket or pyserial port, our protocol, nothing else."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any, TypeVar

import serial

from protocol import Frame, FrameEncoder, NodeKind, StreamDecoder, definitions_hash, messages
from protocol.registry import Message

M = TypeVar("M", bound=Message)
PROGRAM_WAIT_S = 300.0  # a warm build takes a second or two; a cold compile cache minutes on a loaded machine
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


class AgentClient:
    """Sends commands and collects every frame received, in order, in `frames`."""

    def __init__(self, read: Callable[[], bytes], write: Callable[[bytes], Any], close: Callable[[], None]) -> None:
        self._read, self._write, self._close = read, write, close
        self.encoder = FrameEncoder()
        self.decoder = StreamDecoder()
        self.frames: list[Frame] = []
        self._seen = 0

    @classmethod
    def tcp(cls, address: str) -> AgentClient:
        host, port = address.removeprefix("tcp://").rsplit(":", 1)
        sock = socket.create_connection((host, int(port)), timeout=5)
        sock.settimeout(0.05)

        def read() -> bytes:
            try:
                data = sock.recv(65536)
            except TimeoutError:
                return b""
            if not data:
                raise ConnectionError("agent closed the connection")
            return data

        return cls(read, sock.sendall, sock.close)

    @classmethod
    def pty(cls, path: str) -> AgentClient:
        port = serial.Serial(path, 115200, timeout=0.05)
        return cls(lambda: port.read(65536), port.write, port.close)

    def close(self) -> None:
        self._close()

    def send(self, message: Message, flags: int = 0) -> int:
        encoded = self.encoder.encode(message, flags)
        self._write(encoded.wire)
        return encoded.seq

    def send_raw(self, data: bytes) -> None:
        self._write(data)

    def pump(self) -> list[Frame]:
        new = self.decoder.feed(self._read())
        self.frames.extend(new)
        return new

    def wait_for(self, predicate: Callable[[Frame], bool], timeout_s: float = 10.0) -> Frame:
        """The first frame not yet returned by wait_for that satisfies predicate (earlier ones are kept)."""
        deadline = time.monotonic() + timeout_s
        while True:
            for index in range(self._seen, len(self.frames)):
                if predicate(self.frames[index]):
                    self._seen = index + 1
                    return self.frames[index]
            if time.monotonic() > deadline:
                raise TimeoutError("no matching frame")
            self.pump()

    def wait_message(self, kind: type[M], timeout_s: float = 10.0, **fields: Any) -> M:
        frame = self.wait_for(
            lambda f: isinstance(f.message, kind) and all(getattr(f.message, k) == v for k, v in fields.items()),
            timeout_s,
        )
        return frame.message  # type: ignore[return-value]

    def wait_program(self, timeout_s: float = PROGRAM_WAIT_S) -> None:
        """Until the program runs (its first SAMPLE: a starting agent sends none, serve/starting.py), so that commands
        are not answered BUSY; frames read meanwhile stay unseen for wait_for."""
        deadline = time.monotonic() + timeout_s
        while not any(isinstance(f.message, messages.Sample) for f in self.frames):
            if time.monotonic() > deadline:
                raise TimeoutError(f"the agent's program did not run within {timeout_s:g} s")
            self.pump()

    def command(self, message: Message, timeout_s: float = 10.0) -> messages.Ack:
        seq = self.send(message)
        return self.wait_message(messages.Ack, timeout_s, cmd_seq=seq, cmd_msg_id=message.MSG_ID)

    def hello(self) -> None:
        self.send(messages.Hello(protocol_version=1, node_kind=int(NodeKind.GROUND),
                                 definitions_hash=definitions_hash(), node_id=7, boot_id=1234))

    def of(self, kind: type[M]) -> list[M]:
        return [f.message for f in self.frames if isinstance(f.message, kind)]  # type: ignore[misc]


class ServerProcess:
    """`python -m simulator serve ARGS` as a child process; its first stdout line is the address."""

    def __init__(self, args: list[str]) -> None:
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "simulator", "serve", *args],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
        )
        assert self.proc.stdout is not None
        self.address = self.proc.stdout.readline().strip()
        if not self.address:
            self.proc.wait(30)
            why = self.proc.stderr.read() if self.proc.stderr else ""
            self.stop()
            raise RuntimeError(f"server did not start: {why}")

    def stop(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()
        for stream in (self.proc.stdout, self.proc.stderr):
            if stream:
                stream.close()
        return self.proc.returncode


@contextmanager
def running(*args: str) -> Iterator[ServerProcess]:
    server = ServerProcess(list(args))
    try:
        yield server
    finally:
        server.stop()


@contextmanager
def connected(*args: str) -> Iterator[tuple[ServerProcess, AgentClient]]:
    with running(*args) as server:
        client = AgentClient.pty(server.address) if "--pty" in args else AgentClient.tcp(server.address)
        try:
            client.wait_program()
            yield server, client
        finally:
            client.close()
