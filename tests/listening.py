"""Where a port listens, read from /proc/net/tcp{,6} (Linux), and this machine's addresses other than loopback."""

from __future__ import annotations

import contextlib
import ipaddress
import socket
from pathlib import Path

LISTEN = "0A"  # the TCP state column's value for a listening socket


def _address(hex_address: str) -> str:
    """/proc/net/tcp's 0100007F (IPv4, little-endian) or 32 hex digits (IPv6, four little-endian words)."""
    raw = bytes.fromhex(hex_address)
    if len(raw) == 4:
        return str(ipaddress.IPv4Address(raw[::-1]))
    return str(ipaddress.IPv6Address(b"".join(raw[i:i + 4][::-1] for i in range(0, 16, 4))))


def listening_addresses(port: int) -> set[str]:
    """Every local address a socket listens on at `port` (0.0.0.0 or :: for all interfaces)."""
    found = set()
    for table in (Path("/proc/net/tcp"), Path("/proc/net/tcp6")):
        if not table.exists():
            continue
        for line in table.read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, hex_port = local.split(":")
            if state == LISTEN and int(hex_port, 16) == port:
                found.add(_address(address))
    return found


def other_local_addresses() -> list[str]:
    """This machine's IPv4 addresses outside 127/8: the kernel's local routes (/proc/net/fib_trie's "/32 host
    LOCAL" entries) and the default route's source address."""
    found = set()
    trie = Path("/proc/net/fib_trie")
    if trie.exists():
        lines = trie.read_text().splitlines()
        found.update(lines[i - 1].split()[-1] for i, line in enumerate(lines) if "/32 host LOCAL" in line and i > 0)
    with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.connect(("198.51.100.1", 9))  # a UDP connect sends nothing: it only picks the route's source address
        found.add(s.getsockname()[0])
    return sorted(a for a in found if not ipaddress.IPv4Address(a).is_loopback and a != "0.0.0.0")
