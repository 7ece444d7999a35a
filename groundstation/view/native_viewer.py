"""Rerun's native viewer (a window) with its data port for the run's owner alone (issue 38).

rr.spawn (rerun-sdk 0.41) starts `rerun --port 9876` with rerun's default bind, 0.0.0.0: every machine on the
network could read the run from that port and write into the operator's view. Here the viewer runs in a private
network behind the owner's door (web_server.PrivateRerun), detached, so its window outlives the run as rr.spawn's
did. It reaches the display through a unix socket, which every network namespace shares: X on `:N` and Wayland.

Where that cannot be (no private network: macOS, Ubuntu's AppArmor restriction; an X display over TCP, as `ssh -X`
gives, which a private network cannot reach), the viewer listens on 127.0.0.1 only: readable by other local users,
no longer by the network (docs/reliability.md, N11).
"""

from __future__ import annotations

import contextlib
import os
import stat
import subprocess
import tempfile
import time
from pathlib import Path

from groundstation.links.peer import listener_uid
from groundstation.view.errors import PrivateViewerUnavailable, ViewError
from groundstation.view.web_bridge import SOCKET_NAME, listening
from groundstation.view.web_gate import WebGate, connected_inside
from groundstation.view.web_server import HOST, READY_WAIT_S, PrivateRerun, rerun_binary


def _command(port: int, memory_limit: str, server_memory_limit: str) -> list[str]:
    """What rr.spawn runs, with a bind address."""
    return [rerun_binary(), "--port", str(port), "--bind", HOST, "--memory-limit", memory_limit,
            "--server-memory-limit", server_memory_limit, "--expect-data-soon", "--hide-welcome-screen"]


def display_over_network() -> bool:
    """Whether the X display is reached over TCP (`host:N`, as ssh -X sets it) rather than a unix socket."""
    if os.environ.get("WAYLAND_DISPLAY"):
        return False
    host = os.environ.get("DISPLAY", "").rpartition(":")[0]
    return host not in ("", "unix") and not host.startswith("/")


class NativeViewer(PrivateRerun):
    """The native viewer in the private network; its data port is the owner's door at `grpc_port`."""

    def __init__(self, grpc_port: int, memory_limit: str, server_memory_limit: str, folder: Path) -> None:
        super().__init__({b"g": grpc_port}, lambda ports: _command(ports[b"g"], memory_limit, server_memory_limit),
                         detached=True, folder=folder)
        self.grpc_port = self.ports[b"g"]
        self.uri = f"rerun+http://{HOST}:{self.grpc_port}/proxy"


class OpenNativeViewer:
    """A private native viewer a run before this one opened (its window still open): a new door to it at
    `grpc_port`, so the stream goes into the same window, as rr.spawn reuses a viewer on its port."""

    def __init__(self, grpc_port: int, bridge: Path) -> None:
        self._gate = WebGate(HOST, {b"g": grpc_port}, bridge)
        self._gate.start()
        self.grpc_port = self._gate.ports[b"g"]
        self.uri = f"rerun+http://{HOST}:{self.grpc_port}/proxy"
        self.address: str | None = None

    def close(self) -> None:
        """Close the door; the window stays open with what it was sent."""
        self._gate.close()


class LoopbackNativeViewer:
    """The native viewer as rr.spawn starts it, but on 127.0.0.1 only (where no private network can be had)."""

    def __init__(self, grpc_port: int, memory_limit: str, server_memory_limit: str) -> None:
        self.grpc_port = grpc_port
        self.uri = f"rerun+http://{HOST}:{grpc_port}/proxy"
        self.address: str | None = None
        # Said where the viewer's address is said: this door is not the owner's alone (anything that listens says
        # whom it answers).
        self.notice = (f"the native viewer's data port {HOST}:{grpc_port} is readable by every local user here "
                       "(no private network for it on this machine, or the display is over TCP): use --foxglove or "
                       "--rrd FILE on a shared machine")
        if listening(grpc_port):
            return  # a viewer is open there already (rr.spawn's reuse); our own from an earlier run, as a rule
        command = _command(grpc_port, memory_limit, server_memory_limit)
        try:
            process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                       stderr=subprocess.DEVNULL, start_new_session=True,
                                       env={**os.environ, "RERUN_APP_ONLY": "true"})
        except OSError as e:
            raise ViewError(f"cannot start the Rerun viewer ({command[0]}): {e.strerror or e}") from e
        deadline = time.monotonic() + READY_WAIT_S
        while not listening(grpc_port):
            if process.poll() is not None:
                raise ViewError(f"the Rerun viewer stopped at its start (exit code {process.returncode})")
            if time.monotonic() > deadline:
                raise ViewError(f"the Rerun viewer did not listen on port {grpc_port} within {READY_WAIT_S:.0f} s")
            time.sleep(0.05)

    def close(self) -> None:
        """Nothing to stop: the window stays open with what it was sent."""


ServedViewer = PrivateRerun | OpenNativeViewer | LoopbackNativeViewer  # what a live view streams to and closes


def viewer_folder(grpc_port: int) -> Path | None:
    """This user's folder for the private native viewer on `grpc_port` (made 0700, or checked as this user's and
    closed to others): where a later run finds the window still open. None: the name is taken by someone else."""
    folder = Path(tempfile.gettempdir()) / f"dive-{os.geteuid()}-rerun-{grpc_port}"  # short: a socket path
    with contextlib.suppress(FileExistsError):
        folder.mkdir(mode=0o700)
    info = folder.lstat()
    if not stat.S_ISDIR(info.st_mode) or info.st_uid != os.geteuid() or info.st_mode & 0o077:
        return None
    return folder


def _still_open(bridge: Path) -> bool:
    """Whether the bridge at `bridge` still answers (its window open); a socket left by one killed is removed."""
    try:
        connected_inside(bridge, b"g").close()
        return True
    except OSError:
        with contextlib.suppress(OSError):
            bridge.unlink()
        return False


def start_native_viewer(grpc_port: int, memory_limit: str, server_memory_limit: str) -> ServedViewer:
    """The native viewer: the one this user has open on `grpc_port` if there is one, else a new one; private
    where this machine and its display allow it, else on 127.0.0.1."""
    if listening(grpc_port) and listener_uid(grpc_port) not in (os.geteuid(), None):
        raise ViewError(f"port {grpc_port} is another user's: the run would stream to them (choose another with "
                        "--grpc-port)")
    if not display_over_network() and not listening(grpc_port):
        folder = viewer_folder(grpc_port)
        if folder is not None and (folder / SOCKET_NAME).exists() and _still_open(folder / SOCKET_NAME):
            return OpenNativeViewer(grpc_port, folder / SOCKET_NAME)
        viewer = NativeViewer(grpc_port, memory_limit, server_memory_limit,
                              folder or Path(tempfile.mkdtemp(prefix="dive-rerun-")))
        try:
            viewer.serve()
            return viewer
        except PrivateViewerUnavailable:
            pass  # said in the docs: the port is then on loopback, readable by local users
    return LoopbackNativeViewer(grpc_port, memory_limit, server_memory_limit)
