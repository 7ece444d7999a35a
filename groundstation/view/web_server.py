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
from collections.abc import Callable
from pathlib import Path
from urllib.parse import quote

from groundstation.links.peer import table_readable
from groundstation.view.errors import PrivateViewerUnavailable, ViewError
from groundstation.view.web_bridge import NO_PRIVATE_NETWORK, SOCKET_NAME, port_spec
from groundstation.view.web_gate import WebGate, WebGateCounts

HOST = "127.0.0.1"
READY_WAIT_S = 40.0  # the bridge's Python and rerun start in ~0.3 s; a loaded machine may take many seconds
PROBE_WAIT_S = 30.0
STOP_WAIT_S = 5.0
BRIDGE = [sys.executable, "-P", "-m", "groundstation.view.web_bridge"]  # -P: simulator_process.py says why
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


class PrivateRerun:
    """A `rerun` program in a private network (web_bridge.py) behind a door on 127.0.0.1 at the given ports
    (web_gate.py), which lets in the owner's processes only: the base of the web viewer and the native viewer.

    The rerun servers' own ports are in a network namespace of their own, where the same port numbers are free
    whatever this machine runs; the door forwards the owner's connections to them. The recording streams through
    the door too. `detached`: rerun (a window) outlives this process and the door, as rr.spawn's viewer does.
    """

    uri: str  # the data stream's address at the door, which the recording streams to

    def __init__(self, ports: dict[bytes, int], rerun_args: Callable[[dict[bytes, int]], list[str]],
                 detached: bool = False, folder: Path | None = None) -> None:
        # 0700 (mkdtemp's, or the caller's of the owner's own): the bridge's socket is the owner's only
        self._folder = folder or Path(tempfile.mkdtemp(prefix="dive-rerun-"))
        self.bridge_socket = self._folder / SOCKET_NAME  # the owner's way to the private servers (web_gate.py)
        try:  # the ports, taken now (a port in use: OSError)
            self._gate = WebGate(HOST, ports, self.bridge_socket)
        except OSError:
            shutil.rmtree(self._folder, ignore_errors=True)
            raise
        self.ports = self._gate.ports
        self._detached = detached
        self.address: str | None = None  # a page to open, where there is one
        # the children's output, whose last line is the reason if they fail; a detached window's goes nowhere (it
        # would fill a file no process is left to read)
        self._log = tempfile.TemporaryFile()
        rerun = rerun_args(self.ports)
        command = [*BRIDGE, str(self._folder), port_spec(self.ports), "detached" if detached else "attached", *rerun]
        try:
            self._process = subprocess.Popen(command, stdin=subprocess.DEVNULL if detached else subprocess.PIPE,
                                             stdout=subprocess.PIPE,
                                             stderr=subprocess.DEVNULL if detached else self._log,
                                             start_new_session=detached,
                                             env={**os.environ, "RERUN_APP_ONLY": "true"})
        except OSError as e:
            self._release()
            raise ViewError(f"cannot start Rerun ({rerun[0]}): {e.strerror or e}") from e

    def serve(self) -> None:
        """Wait for the bridge's `ready` and open the door; on any failure stop everything and raise."""
        try:
            self._wait_ready()
        except BaseException:
            self.stop()
            raise
        self._gate.start()

    def _wait_ready(self) -> None:
        """The bridge's first line: `ready`, or `error: why` (its exit code NO_PRIVATE_NETWORK: none here)."""
        assert self._process.stdout is not None
        deadline = time.monotonic() + READY_WAIT_S
        line = b""
        while not line.endswith(b"\n"):
            left_s = deadline - time.monotonic()
            if left_s <= 0:
                raise ViewError(f"Rerun did not listen on ports {port_spec(self.ports)} within {READY_WAIT_S:.0f} s")
            if select.select([self._process.stdout], [], [], min(left_s, 0.5))[0]:
                byte = os.read(self._process.stdout.fileno(), 1)
                if not byte:
                    break
                line += byte
        text = line.decode(errors="replace").strip()
        if text == "ready":
            return
        if text.startswith("error: ") and self._process.wait(STOP_WAIT_S) == NO_PRIVATE_NETWORK:
            raise PrivateViewerUnavailable(text.removeprefix("error: "))
        raise ViewError(f"Rerun stopped at its start: {self._last_line() or text}")

    def _last_line(self) -> str:
        self._log.seek(0)
        text = _STYLE.sub("", self._log.read().decode(errors="replace"))
        lines = [line.strip() for line in text.splitlines() if line.strip()]
        return lines[-1][-300:] if lines else f"exit code {self._process.returncode}"

    @property
    def counts(self) -> WebGateCounts:
        """What the door did (web_gate.WebGateCounts)."""
        return self._gate.counts

    def stop(self) -> None:
        """Close the door and stop the child, detached or not (the window closes)."""
        self._detached = False
        self.close()

    def close(self) -> None:
        """Close the door; stop the child unless it is detached (a window stays open with what it was sent)."""
        self._gate.close()
        if not self._detached and self._process.poll() is None:
            if self._process.stdin is not None:
                with contextlib.suppress(OSError):
                    self._process.stdin.close()  # the bridge's sign to stop rerun and end
            else:
                self._process.terminate()  # a detached bridge reads no stdin; SIGTERM makes it tidy up
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
        if not self._detached or self._process.poll() is not None:  # a detached bridge removes its own folder
            shutil.rmtree(self._folder, ignore_errors=True)


class WebViewerServer(PrivateRerun):
    """The web viewer's page server and gRPC data stream, for the owner alone, at `web_port` and `grpc_port`.

    Not rerun-sdk's serve_web_viewer (0.41 listens on every interface) nor a plain `rerun --serve-web --bind
    127.0.0.1` (any local user could read it): the rerun CLI's `--serve-web` in the private network.
    """

    def __init__(self, web_port: int, grpc_port: int, server_memory_limit: str) -> None:
        super().__init__({b"w": web_port, b"g": grpc_port}, lambda ports: [
            rerun_binary(), "--serve-web", "--bind", HOST, "--web-viewer-port", str(ports[b"w"]),
            "--port", str(ports[b"g"]), "--server-memory-limit", server_memory_limit])
        self.web_port, self.grpc_port = self.ports[b"w"], self.ports[b"g"]
        self.uri = f"rerun+http://{HOST}:{self.grpc_port}/proxy"
        self.address = f"http://{HOST}:{self.web_port}/?url={quote(self.uri, safe='')}"

    @classmethod
    def start(cls, web_port: int, grpc_port: int, server_memory_limit: str) -> WebViewerServer:
        """The two servers, listening: a ViewError (with the reason) if they do not come up; PrivateViewerUnavailable
        (its line says what works instead) if this machine gives no private network."""
        server = cls(web_port, grpc_port, server_memory_limit)
        try:
            server.serve()
        except PrivateViewerUnavailable as e:
            raise PrivateViewerUnavailable(private_refusal(str(e))) from None
        return server


def private_refusal(reason: str) -> str:
    """The one line for a machine where the web viewer cannot be kept to its owner, and what works instead."""
    return (f"--viewer web cannot keep its servers to you on this machine ({reason}), and every local user could "
            "read them: use Foxglove (--foxglove), which answers your user only, or a file (--rrd FILE)")
