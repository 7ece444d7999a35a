"""The web viewer's private network (Linux): a program that moves into a network of its own, starts the `rerun` web
server there, and hands the run's owner connected sockets to it over a unix socket.

Why (issue 38): `rerun --serve-web` has no hook at accept, no unix socket and no token, so whatever it listens on
in the machine's network any local user can read. Here it listens in a network namespace of this process's own
(an unprivileged user namespace owns it: no root needed), where no other process can reach 127.0.0.1. The one way
in is `bridge.sock`, a unix socket in the run's folder (0700, socket 0600: the owner and root only; a path on the
file system is the same in every network namespace): a client sends one byte naming the port (`w` the page, `g` the
data stream) and gets back a TCP socket connected to it inside, by SCM_RIGHTS. A socket keeps the namespace it was
made in, so the owner's process then reads and writes the server directly, with no copy here
(view/web_gate.py is the door on 127.0.0.1 that a browser reaches).

Run as `python -m groundstation.view.web_bridge FOLDER w=PORT,g=PORT MODE RERUN ARGS...` (web_server.py does):
the first line on stdout is `ready` once rerun listens on every port, or `error: <why>`. MODE `attached` (the web
viewer): it ends when its stdin closes (dive ended), when dive dies (PR_SET_PDEATHSIG), or when rerun does.
`detached` (the native viewer, whose window outlives the run that opened it, as rr.spawn's does): it ends when
rerun does. Either way it removes FOLDER at its end. Standard library only.
"""

from __future__ import annotations

import contextlib
import ctypes
import fcntl
import os
import selectors
import shutil
import signal
import socket
import struct
import subprocess
import sys
import time
from pathlib import Path

HOST = "127.0.0.1"
SOCKET_NAME = "bridge.sock"
READY_WAIT_S = 30.0  # rerun starts in ~0.1 s; a loaded machine may take seconds
CONNECT_WAIT_S = 2.0
_CLONE_NEWUSER = 0x10000000
_CLONE_NEWNET = 0x40000000
_SIOCGIFFLAGS, _SIOCSIFFLAGS, _IFF_UP = 0x8913, 0x8914, 0x1
_PR_SET_PDEATHSIG = 1
NO_PRIVATE_NETWORK = 3  # the exit code that says this machine gives no private network (others: rerun failed)
RERUN_FAILED = 4


class PrivateNetworkError(OSError):
    """This machine does not let an unprivileged process have a network of its own."""


def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


def die_with_parent() -> None:
    """Linux: this process gets SIGTERM when its parent dies, even by kill -9, so nothing keeps serving the data."""
    with contextlib.suppress(OSError, AttributeError):
        _libc().prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)


def enter_private_network() -> None:
    """Move this (single-threaded) process into a new user and network namespace, as the same uid and gid, with
    its loopback up. A PrivateNetworkError says why not (no such call: not Linux; EPERM/ENOSPC: user namespaces off,
    as under Ubuntu's AppArmor restriction or `user.max_user_namespaces = 0`)."""
    uid, gid = os.getuid(), os.getgid()
    try:
        unshare = _libc().unshare
    except AttributeError as e:
        raise PrivateNetworkError("no unshare() on this system (Linux only)") from e
    if unshare(_CLONE_NEWUSER | _CLONE_NEWNET) != 0:
        errno = ctypes.get_errno()
        raise PrivateNetworkError(errno, f"unprivileged user namespaces are not allowed here: {os.strerror(errno)}")
    try:  # the same ids inside as outside, so files and the peer check below see the owner (setgroups first: a rule)
        Path("/proc/self/setgroups").write_text("deny")
        Path("/proc/self/uid_map").write_text(f"{uid} {uid} 1")
        Path("/proc/self/gid_map").write_text(f"{gid} {gid} 1")
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:  # a new namespace's loopback starts down
            request = struct.pack("16sh14x", b"lo", 0)
            flags = struct.unpack("16sh", fcntl.ioctl(s, _SIOCGIFFLAGS, request)[:18])[1]
            fcntl.ioctl(s, _SIOCSIFFLAGS, struct.pack("16sh14x", b"lo", flags | _IFF_UP))
    except OSError as e:
        raise PrivateNetworkError(e.errno, f"cannot set up the private network: {e.strerror or e}") from e


def listening(port: int) -> bool:
    """Whether something accepts on 127.0.0.1:`port` (in whichever network namespace the caller is)."""
    with socket.socket() as s:
        s.settimeout(0.5)
        return s.connect_ex((HOST, port)) == 0


def _wait_ready(rerun: subprocess.Popen[bytes], ports: list[int]) -> str | None:
    """None once every port listens; else why not."""
    deadline = time.monotonic() + READY_WAIT_S
    while not all(listening(port) for port in ports):
        if rerun.poll() is not None:
            return f"rerun stopped at its start (exit code {rerun.returncode})"
        if time.monotonic() > deadline:
            return f"rerun did not listen on ports {', '.join(map(str, ports))} within {READY_WAIT_S:.0f} s"
        time.sleep(0.05)
    return None


def _hand_over(client: socket.socket, ports: dict[bytes, int]) -> None:
    """One request: a byte naming the port in, a connected socket to it out (or `-` and nothing)."""
    with client:
        client.settimeout(CONNECT_WAIT_S)
        uid = struct.unpack("3i", client.getsockopt(socket.SOL_SOCKET, socket.SO_PEERCRED, 12))[1]
        if uid != os.getuid():  # the folder's mode keeps others out already (only root passes it, and root shows
            return  # here as the overflow uid unless it runs the bridge): this holds if someone loosens the mode
        try:
            port = ports.get(client.recv(1))
            if port is None:
                return
            with socket.create_connection((HOST, port), timeout=CONNECT_WAIT_S) as inner:
                socket.send_fds(client, [b"+"], [inner.fileno()])
        except OSError:
            with contextlib.suppress(OSError):
                client.sendall(b"-")


def serve(folder: Path, ports: dict[bytes, int], detached: bool, rerun_command: list[str]) -> int:
    """The program: the private network, rerun in it, then hand-overs until rerun ends (attached: or stdin closes)."""
    if not detached:
        die_with_parent()
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))  # stopped: stop rerun and tidy up first (finally below)
    try:
        enter_private_network()
    except PrivateNetworkError as e:
        print(f"error: {e.strerror or e}", flush=True)
        return NO_PRIVATE_NETWORK
    old_mask = os.umask(0o177)  # the socket file is made 0600 by bind, never looser for a moment
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(str(folder / SOCKET_NAME))
    os.umask(old_mask)
    listener.listen(16)
    # rerun's output goes where ours does (dive's log of it, or nowhere), never into the pipe of our `ready` line,
    # which nobody reads after it: a full pipe would stop rerun
    rerun = subprocess.Popen(rerun_command, stdin=subprocess.DEVNULL, stdout=sys.stderr, preexec_fn=die_with_parent)
    try:
        problem = _wait_ready(rerun, list(ports.values()))
        print(f"error: {problem}" if problem else "ready", flush=True)
        if problem:
            return RERUN_FAILED
        with selectors.DefaultSelector() as selector:
            selector.register(listener, selectors.EVENT_READ, "accept")
            if not detached:
                selector.register(sys.stdin, selectors.EVENT_READ, "stdin")
            while rerun.poll() is None:
                for key, _ in selector.select(0.5):
                    if key.data == "stdin" and not os.read(sys.stdin.fileno(), 4096):
                        return 0  # dive closed our stdin: the view is over
                    if key.data == "accept":
                        with contextlib.suppress(OSError):
                            _hand_over(listener.accept()[0], ports)
        return 0
    finally:
        listener.close()
        if rerun.poll() is None:
            rerun.terminate()
            try:
                rerun.wait(5.0)
            except subprocess.TimeoutExpired:
                rerun.kill()
                rerun.wait()
        shutil.rmtree(folder, ignore_errors=True)  # dive may be gone (kill -9, or a window that outlived its run)


def port_spec(ports: dict[bytes, int]) -> str:
    """`w=9090,g=9876`: the ports argument, from the byte that names each port to its number."""
    return ",".join(f"{which.decode()}={port}" for which, port in ports.items())


def _parse_ports(spec: str) -> dict[bytes, int]:
    ports = {}
    for item in spec.split(","):
        which, _, port = item.partition("=")
        ports[which.encode()] = int(port)
    return ports


def probe() -> int:
    """`--probe`: whether this machine gives this user a private network (the CLI asks before it starts a run)."""
    try:
        enter_private_network()
    except PrivateNetworkError as e:
        print(f"error: {e.strerror or e}", flush=True)
        return NO_PRIVATE_NETWORK
    print("ready", flush=True)
    return 0


def main(argv: list[str]) -> int:
    if argv == ["--probe"]:
        return probe()
    if len(argv) < 4 or argv[2] not in ("attached", "detached"):
        print("error: usage: python -m groundstation.view.web_bridge FOLDER w=PORT,g=PORT attached|detached RERUN "
              "[ARGS...]", flush=True)
        return 2
    return serve(Path(argv[0]), _parse_ports(argv[1]), argv[2] == "detached", argv[3:])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
