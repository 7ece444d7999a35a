"""A replaced client gets the "link taken" notice even when it is still writing as the new client connects."""

from __future__ import annotations

import socket
import time

from simulator.serve.transport import tell_replaced


def test_a_replaced_client_still_writing_reads_the_notice_and_a_clean_close() -> None:
    """Bytes the old ground sends after the agent's last drain used to turn the agent's close into a reset: the
    ground's next write (a HEARTBEAT) then failed, its session dropped the connection with the notice unread, and
    it reconnected and took the link back (test_one_owner's takeover test, "the run did not end")."""
    with socket.create_server(("127.0.0.1", 0)) as listener:
        ground = socket.create_connection(listener.getsockname()[:2], timeout=5.0)
        agent_side, _ = listener.accept()
        agent_side.setblocking(False)  # as the transport keeps its client
        with ground:
            tell_replaced(agent_side, b"\x00NOTICE")
            ground.sendall(b"a command sent as the other ground connected")
            ground.recv(1, socket.MSG_PEEK)  # the notice is there: the late bytes have reached the agent too
            agent_side.close()  # what the transport does right after telling
            time.sleep(0.05)  # (a reset, had the close sent one, has reached the ground)
            ground.sendall(b"the ground's next HEARTBEAT, before it reads")  # a reset would raise here
            received = b""
            while chunk := ground.recv(4096):
                received += chunk
    assert received == b"\x00NOTICE"
