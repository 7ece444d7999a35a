"""The QEMU build's TCP front tells a replaced client "link taken by another ground" and forwards it no more."""

from __future__ import annotations

import socket
import time

from protocol import FrameEncoder, StreamDecoder
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


def test_a_new_client_gets_a_frame_that_starts_the_boards_next_chunk_whole() -> None:
    """The board idle between steps: its next bytes start a frame (the ACK of the client's first command), which the
    new client must get whole; only a frame another client got the start of is cut off (dive check on
    sim://?firmware=qemu&speed=5 lost its first command's ACK that way)."""
    uart, board_uart = socket.socketpair()
    events, board_events = socket.socketpair()
    relay = LinkRelay("127.0.0.1", 0, uart, events)
    host, port = relay.address.removeprefix("tcp://").split(":")
    ack = FrameEncoder(7).encode(m.Ack(cmd_msg_id=m.ParamGet.MSG_ID, cmd_seq=5, result=0, reason="")).wire
    text = FrameEncoder(8).encode(m.Text(t_us=1, severity=1, text="a frame cut in two")).wire
    try:
        first = socket.create_connection((host, int(port)), timeout=5.0)
        assert board_events.recv(1) == LINK_UP
        board_uart.sendall(text[:5])  # the first client gets a frame's start ...
        assert first.recv(100) == text[:5]
        second = socket.create_connection((host, int(port)), timeout=5.0)
        assert board_events.recv(1) == LINK_UP
        board_uart.sendall(text[5:])  # ... the second must not get its rest
        time.sleep(0.2)
        board_uart.sendall(ack)  # and the board's next frame starts a chunk: whole
        received = b""
        second.settimeout(5.0)
        while not (frames := StreamDecoder().feed(received)):
            received += second.recv(4096)
        assert [type(f.message) for f in frames] == [m.Ack] and frames[0].seq == 7
        third = socket.create_connection((host, int(port)), timeout=5.0)  # the stream at a frame boundary now
        assert board_events.recv(1) == LINK_UP
        board_uart.sendall(ack)
        third.settimeout(5.0)
        received = b""
        while not (frames := StreamDecoder().feed(received)):
            received += third.recv(4096)
        assert [type(f.message) for f in frames] == [m.Ack]
        for s in (first, second, third):
            s.close()
    finally:
        relay.close()
        for s in (uart, board_uart, events, board_events):
            s.close()
