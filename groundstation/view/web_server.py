"""Rerun's web viewer and its data stream for the run's owner alone: a `rerun --serve-web` child in a private network
(web_bridge.py), reached through a door on 127.0.0.1 that lets in the owner's processes only (web_gate.py)."""

from __future__ import annotations

import contextlib
import importlib.util
import os
import re
import select
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from urllib.parse import quote

from groundstation.links.peer import table_readable
from groundstation.view.errors import PrivateViewerUnavailable, ViewError
from groundstation.view.web_bridge import NO_PRIVATE_NETWORK, SOCKET_NAME
from groundstation.view.web_gate import WebGate, WebGateCounts

HOST = "127.0.0.1"
READY_WAIT_S = 40.0  # the bridge's Python and rerun start in ~0.3 s; a loaded machine may take many seconds
PROBE_WAIT_S = 30.0
STOP_WAIT_S = 5.0
BRIDGE = [sys.executable, "-m", "groundstation.view.web_bridge"]
_STYLE = re.compile(r"\x1b\[[0-9;]*[A-Za-z]")  # the child's log colours its lines even into a file


def rerun_executable() -> str:
    """The `rerun` CLI that rerun-sdk installs beside this Python (or the one on PATH)."""
    return shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))


def rerun_binary() -> str:
    """The rerun program itself, not its Python wrapper script (which runs it as a child of its own, so stopping
    the wrapper would leave the servers up); the wrapper where the binary is not found."""
    spec = importlib.util.find_spec("rerun_cli")
    if spec is not None and spec.origin is not None:
        folder = Path(spec.origin).parent
        for candidate in (folder / "Rerun.app" / "Contents" / "MacOS" / "Rerun", folder / "rerun"):
            if candidate.is_file():
                return str(candidate)
    return rerun_executable()


def private_network_problem() -> str | None:
    """Why this machine cannot serve the web viewer to its owner alone (None: it can). Asked by a child process
    of the bridge's own code, so the answer is what the bridge will meet."""
    if not sys.platform.startswith("linux"):
        return "it needs Linux network namespaces"
    if not table_readable():
        return "the kernel's socket table (/proc/net/tcp) cannot be read to tell the owner's connections"
    try:
        done = subprocess.run([*BRIDGE, "--probe"], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                              timeout=PROBE_WAIT_S)
    except (OSError, subprocess.TimeoutExpired) as e:
        return f"its helper did not answer ({e})"
    lines = done.stdout.splitlines()
    if done.returncode == 0 and lines[:1] == ["ready"]:
        return None
    return (lines[0].removeprefix("error: ") if lines else f"its helper failed (exit code {done.returncode})")


class WebViewerServer:
    """The web viewer's page server and gRPC data stream, private, behind a door on 127.0.0.1 at the given ports.

    Not rerun-sdk's serve_web_viewer (0.41 listens on every interface) nor a plain `rerun --serve-web --bind
    127.0.0.1` (any local user could read it): the rerun CLI's servers run in a network namespace of their own,
    where the same port numbers are free whatever this machine runs, and the door forwards the owner's connections
    to them. The recording streams through the door too, as the browser's data does.
    """

    def __init__(self, web_port: int, grpc_port: int, server_memory_limit: str) -> None:
        self._folder = Path(tempfile.mkdtemp(prefix="dive-web-"))  # 0700: the bridge's socket is the owner's only
        try:  # the ports, taken now (a port in use: OSError)
            self._gate = WebGate(HOST, {b"w": web_port, b"g": grpc_port}, self._folder / SOCKET_NAME)
        except OSError:
            shutil.rmtree(self._folder, ignore_errors=True)
            raise
        self.web_port, self.grpc_port = self._gate.ports[b"w"], self._gate.ports[b"g"]
        self.bridge_socket = self._folder / SOCKET_NAME  # the owner's way to the private servers (web_gate.py)
        self.uri = f"rerun+http://{HOST}:{self.grpc_port}/proxy"
        self.address = f"http://{HOST}:{self.web_port}/?url={quote(self.uri, safe='')}"
        self._log = tempfile.TemporaryFile()  # the children's output: its last line is the reason if they fail
        rerun = [rerun_binary(), "--serve-web", "--bind", HOST, "--web-viewer-port", str(self.web_port),
                 "--port", str(self.grpc_port), "--server-memory-limit", server_memory_limit]
        command = [*BRIDGE, str(self._folder), str(self.web_port), str(self.grpc_port), *rerun]
        try:
            self._process = subprocess.Popen(command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                             stderr=self._log)
        except OSError as e:
            self._release()
            raise ViewError(f"cannot start the Rerun web viewer ({rerun[0]}): {e.strerror or e}") from e

    @classmethod
    def start(cls, web_port: int, grpc_port: int, server_memory_limit: str) -> WebViewerServer:
        """The two servers, listening: a ViewError (with the reason) if they do not come up; PrivateViewerUnavailable
        if this machine gives no private network."""
        server = cls(web_port, grpc_port, server_memory_limit)
        try:
            server._wait_ready()
        except BaseException:
            server.close()
            raise
        server._gate.start()
        return server

    def _wait_ready(self) -> None:
        """The bridge's first line: `ready`, or `error: why` (its exit code NO_PRIVATE_NETWORK: none here)."""
        assert self._process.stdout is not None
        deadline = time.monotonic() + READY_WAIT_S
        line = b""
        while not line.endswith(b"\n"):
            left_s = deadline - time.monotonic()
            if left_s <= 0:
                raise ViewError(f"the Rerun web viewer did not listen on ports {self.web_port} and {self.grpc_port} "
                                f"within {READY_WAIT_S:.0f} s")
            if select.select([self._process.stdout], [], [], min(left_s, 0.5))[0]:
                byte = os.read(self._process.stdout.fileno(), 1)
                if not byte:
                    break
                line += byte
        text = line.decode(errors="replace").strip()
        if text == "ready":
            return
        if text.startswith("error: ") and self._process.wait(STOP_WAIT_S) == NO_PRIVATE_NETWORK:
            raise PrivateViewerUnavailable(private_refusal(text.removeprefix("error: ")))
        raise ViewError(f"the Rerun web viewer stopped at its start: {self._last_line() or text}")

    def _last_line(self) -> str:
        self._log.seek(0)
        text = _STYLE.sub("", self._log.read().decode(errors="replace"))
        lines = [line.strip() for line in text.splitlines() if line.strip()]
        return lines[-1][-300:] if lines else f"exit code {self._process.returncode}"

    @property
    def counts(self) -> WebGateCounts:
        """What the door did (web_gate.WebGateCounts)."""
        return self._gate.counts

    def close(self) -> None:
        """Stop the door and the child (the viewer page and its data go with them)."""
        self._gate.close()
        if self._process.poll() is None:
            with contextlib.suppress(OSError):
                assert self._process.stdin is not None
                self._process.stdin.close()  # the bridge's sign to stop rerun and end
            try:
                self._process.wait(STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                self._process.terminate()  # rerun dies with it (PR_SET_PDEATHSIG)
                try:
                    self._process.wait(STOP_WAIT_S)
                except subprocess.TimeoutExpired:
                    self._process.kill()
                    self._process.wait()
        for pipe in (self._process.stdin, self._process.stdout):
            with contextlib.suppress(OSError, ValueError):
                if pipe is not None:
                    pipe.close()
        self._release()

    def _release(self) -> None:
        self._gate.close()
        self._log.close()
        shutil.rmtree(self._folder, ignore_errors=True)


def private_refusal(reason: str) -> str:
    """The one line for a machine where the web viewer cannot be kept to its owner, and what works instead."""
    return (f"--viewer web cannot keep its servers to you on this machine ({reason}), and every local user could "
            "read them: use the native viewer (--viewer spawn), Foxglove (--foxglove) or a file (--rrd FILE)")
