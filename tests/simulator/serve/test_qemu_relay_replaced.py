"""The QEMU build's TCP front tells a replaced client "link taken by another ground" and forwards it no more."""

from __future__ import annotations

import socket

from protocol import StreamDecoder
from protocol import messages as m
from protocol.enums import LINK_TAKEN_TEXT
from simulator.serve.qemu_relay import LINK_UP, LinkRelay


def test_a_replaced_client_reads_the_notice_and_its_bytes_no_longer_reach_the_board() -> None:
    """QEMU's UART sockets are socket pairs here (the relay's other side); the grounds are real TCP clients."""
    uart, board_uart = socket.socketpair()
    events, board_events = socket.socketpair()
    relay = LinkRelay("127.0.0.1", 0, uart, events)
    host, port = relay.address.removeprefix("tcp://").split(":")
    try:
        first = socket.create_connection((host, int(port)), timeout=5.0)
        assert board_events.recv(1) == LINK_UP
        first.sendall(b"from the first ground")
        board_uart.settimeout(5.0)
        assert board_uart.recv(100) == b"from the first ground"
        second = socket.create_connection((host, int(port)), timeout=5.0)
        assert board_events.recv(1) == LINK_UP
        first.sendall(b"late, from the replaced ground")  # read by the relay, forwarded nowhere
        received = b""
        while chunk := first.recv(4096):  # the notice, then a clean close (a reset would raise here)
            received += chunk
        first.close()
        texts = [f.message for f in StreamDecoder().feed(received) if isinstance(f.message, m.Text)]
        assert [t.text for t in texts] == [LINK_TAKEN_TEXT]
        second.sendall(b"from the second ground")
        assert board_uart.recv(100) == b"from the second ground"  # and nothing of the replaced one before it
        second.close()
    finally:
        relay.close()
        for s in (uart, board_uart, events, board_events):
            s.close()
