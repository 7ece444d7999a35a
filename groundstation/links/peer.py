"""Whose process is at the other end of an accepted loopback TCP connection: the kernel's socket table says (Linux).

Why the kernel's table and not a token alone: the Foxglove app cannot prove a secret (its protocol has no login),
and a listener that closes another user's connection at accept costs them every slot too (issue 38 N1, N2). On
Linux every user may read /proc/net/tcp and /proc/net/tcp6: the peer's own socket is there, its local address
being our peer address, with the uid of the process that opened it. Elsewhere (macOS has no /proc) the answer is
None: the caller falls back to a secret (the hub's token handshake, a token in the Foxglove URL).
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import socket
import struct
from collections.abc import Iterator
from pathlib import Path

TABLES = (Path("/proc/net/tcp"), Path("/proc/net/tcp6"))
LISTEN = "0A"  # the state column's value for a listening socket
TABLE_LIMIT_BYTES = 64 * 1024 * 1024  # a machine with a million sockets still answers; more is not read


def _hex_address(host: str, port: int, width: int) -> str:
    """The kernel's spelling of an address in /proc/net/tcp(6): 32-bit words in host order, then the port."""
    address = ipaddress.ip_address(host)
    if width == 16 and address.version == 4:
        address = ipaddress.IPv6Address(b"\0" * 10 + b"\xff\xff" + address.packed)  # v4-mapped, as tcp6 lists it
    packed = address.packed
    if len(packed) != width:
        return ""
    words = struct.unpack(f"={width // 4}I", packed)
    return "".join(f"{word:08X}" for word in words) + f":{port:04X}"


def _rows(table: Path) -> Iterator[list[str]]:
    """The fields of each socket row of one kernel table (read bounded), none where it cannot be read."""
    try:
        with table.open("rb") as lines:
            text = lines.read(TABLE_LIMIT_BYTES).decode("ascii", "replace")
    except OSError:
        return
    for line in text.splitlines()[1:]:
        fields = line.split()
        if len(fields) > 7:
            yield fields


def peer_uid(sock: socket.socket) -> int | None:
    """The uid owning the other end of `sock` (an accepted TCP connection on this machine); None where the kernel's
    table cannot tell (no /proc, or the peer is not on this machine, or it is already gone)."""
    try:
        peer_host, peer_port = sock.getpeername()[:2]
        our_host, our_port = sock.getsockname()[:2]
    except OSError:
        return None
    for table in TABLES:
        width = 16 if table.name.endswith("6") else 4
        local, remote = _hex_address(peer_host, peer_port, width), _hex_address(our_host, our_port, width)
        if not local or not remote:
            continue
        for fields in _rows(table):
            if fields[1] == local and fields[2] == remote:
                try:
                    return int(fields[7])
                except ValueError:
                    return None
    return None


def listener_uid(port: int) -> int | None:
    """The uid that owns the socket listening on 127.0.0.1:`port` (or on every address); None where the kernel's
    table cannot tell or nothing listens there."""
    for table in TABLES:
        width = 16 if table.name.endswith("6") else 4
        wanted = {_hex_address(host, port, width) for host in ("127.0.0.1", "0.0.0.0")}
        if width == 16:
            wanted.add(_hex_address("::", port, width))
        for fields in _rows(table):
            if fields[3] == LISTEN and fields[1] in wanted:
                with contextlib.suppress(ValueError):
                    return int(fields[7])
    return None


def table_readable() -> bool:
    """Whether this machine has the kernel's table at all (Linux): if it does, a peer not found in it is refused."""
    return TABLES[0].exists()


def peer_is_owner(sock: socket.socket) -> bool | None:
    """True: the peer runs as our user (or as root, who can read the run's token and its key files anyway: a
    `sudo dive surface` still reaches the run); False: as another (or it cannot be found on a machine that can
    tell); None: this machine cannot tell (no /proc): decide by a secret instead."""
    if not table_readable():
        return None
    return peer_uid(sock) in (os.geteuid(), 0)
