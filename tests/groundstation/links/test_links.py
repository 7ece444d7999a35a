"""Links by URL: schemes, clear errors, byte streams over real sockets and pyserial URLs."""

from __future__ import annotations

import socket

import pytest

from groundstation.errors import LinkError, UnknownSchemeError
from groundstation.links import default_url, make_link, open_link
from groundstation.links.memory import MemoryLink
from groundstation.links.sim import sim_arguments


def test_unknown_scheme_names_the_schemes_that_work() -> None:
    with pytest.raises(UnknownSchemeError, match="tcp://.*serial://"):
        make_link("udp://1.2.3.4:5")


def test_unreachable_host_is_a_link_error_naming_the_url() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound but not listening: connection refused
        with pytest.raises(LinkError, match=f"tcp://127.0.0.1:{port}: cannot connect"):
            open_link(f"tcp://127.0.0.1:{port}")


def test_missing_serial_device_is_a_link_error() -> None:
    with pytest.raises(LinkError, match="cannot open /dev/ttyNOPE"):
        open_link("serial:///dev/ttyNOPE?baud=115200")


def test_tcp_link_carries_bytes_both_ways_with_recv_timeout() -> None:
    with socket.create_server(("127.0.0.1", 0)) as server:
        link = open_link(f"tcp://127.0.0.1:{server.getsockname()[1]}")
        peer, _ = server.accept()
        with link, peer:
            assert link.recv(0.05) == b""  # timeout: nothing yet
            link.send(b"\x01\x02\x00")
            assert peer.recv(10) == b"\x01\x02\x00"
            peer.sendall(b"abc")
            assert link.recv(1.0) == b"abc"
            peer.close()
            with pytest.raises(LinkError, match="closed"):
                link.recv(1.0)


def test_pyserial_loop_url_echoes() -> None:
    with open_link("loop://") as link:
        link.send(b"hello\x00")
        assert link.recv(1.0) == b"hello\x00"


def test_memory_pair_and_default_url(monkeypatch: pytest.MonkeyPatch) -> None:
    a, b = MemoryLink.pair()
    a.open()
    b.open()
    a.send(b"x")
    assert b.recv(0.5) == b"x"
    a.close()
    with pytest.raises(LinkError):
        b.recv(0.5)
    assert default_url() == "sim://"
    monkeypatch.setenv("DIVE_URL", "tcp://10.0.0.7:23")
    assert default_url() == "tcp://10.0.0.7:23"


def test_sim_url_query_becomes_simulator_options() -> None:
    args = sim_arguments("sim://?speed=max&seed=3&drop=0.05&disconnect_every=5")
    assert args == ["serve", "--tcp", "127.0.0.1:0", "--speed", "max", "--seed", "3", "--drop", "0.05",
                    "--disconnect-every", "5"]
    with pytest.raises(LinkError, match="tcp"):
        sim_arguments("sim://?tcp=1.2.3.4:5")
