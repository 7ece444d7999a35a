"""Rerun's web viewer and its data stream, served by a `rerun --serve-web` child that listens on 127.0.0.1 only."""

from __future__ import annotations

import contextlib
import ctypes
import importlib.util
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from urllib.parse import quote

from groundstation.view.errors import ViewError

HOST = "127.0.0.1"
READY_WAIT_S = 30.0  # the child starts in ~0.1 s; a loaded machine may take seconds
STOP_WAIT_S = 5.0
_PR_SET_PDEATHSIG = 1
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


def _die_with_parent() -> None:
    """Linux: the child gets SIGTERM when dive dies, even by kill -9, so no orphan keeps serving the data."""
    with contextlib.suppress(OSError, AttributeError):
        ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)


def _listening(port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex((HOST, port)) == 0


class WebViewerServer:
    """The web viewer's page server and the gRPC data stream, both bound to 127.0.0.1 (`--bind`).

    Not rerun-sdk's serve_web_viewer: in 0.41 it takes no bind address and listens on every interface. The rerun
    CLI's `--serve-web` hosts both servers with `--bind`; the recording streams to it as to a spawned viewer.
    """

    def __init__(self, web_port: int, grpc_port: int, server_memory_limit: str) -> None:
        self.web_port, self.grpc_port = web_port, grpc_port
        self.uri = f"rerun+http://{HOST}:{grpc_port}/proxy"
        self.address = f"http://{HOST}:{web_port}/?url={quote(self.uri, safe='')}"
        self._log = tempfile.TemporaryFile()  # the child's output: its last line is the reason if it fails
        command = [rerun_binary(), "--serve-web", "--bind", HOST, "--web-viewer-port", str(web_port),
                   "--port", str(grpc_port), "--server-memory-limit", server_memory_limit]
        preexec = _die_with_parent if sys.platform.startswith("linux") else None
        try:
            self._process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=self._log,
                                             stderr=subprocess.STDOUT, preexec_fn=preexec)
        except OSError as e:
            self._log.close()
            raise ViewError(f"cannot start the Rerun web viewer ({command[0]}): {e.strerror or e}") from e

    @classmethod
    def start(cls, web_port: int, grpc_port: int, server_memory_limit: str) -> WebViewerServer:
        """The two servers, listening: a ViewError (with the child's last line) if they do not come up."""
        server = cls(web_port, grpc_port, server_memory_limit)
        try:
            server._wait_ready()
        except BaseException:
            server.close()
            raise
        return server

    def _wait_ready(self) -> None:
        deadline = time.monotonic() + READY_WAIT_S
        while not (_listening(self.web_port) and _listening(self.grpc_port)):
            if self._process.poll() is not None:
                raise ViewError(f"the Rerun web viewer stopped at its start: {self._last_line()}")
            if time.monotonic() > deadline:
                raise ViewError(f"the Rerun web viewer did not listen on ports {self.web_port} and "
                                f"{self.grpc_port} within {READY_WAIT_S:.0f} s")
            time.sleep(0.05)

    def _last_line(self) -> str:
        self._log.seek(0)
        text = _STYLE.sub("", self._log.read().decode(errors="replace"))
        lines = [line.strip() for line in text.splitlines() if line.strip()]
        return lines[-1][-300:] if lines else f"exit code {self._process.returncode}"

    def close(self) -> None:
        """Stop the child (the viewer page and its data go with it)."""
        if self._process.poll() is None:
            self._process.terminate()
            try:
                self._process.wait(STOP_WAIT_S)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
        self._log.close()
