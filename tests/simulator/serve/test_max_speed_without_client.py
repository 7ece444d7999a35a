"""At --speed max the virtual agent runs as fast as its client reads, so with no client its clock stands still."""

from __future__ import annotations

import time

from protocol import messages
from tests.simulator.agent_client import AgentClient, running


def test_agent_time_does_not_run_ahead_while_no_client_is_connected() -> None:
    with running("--tcp", "127.0.0.1:0", "--speed", "max", "--seed", "3") as server:
        time.sleep(1.5)  # before the fix, thousands of agent seconds passed here, sent to nobody
        client = AgentClient.tcp(server.address)
        try:
            assert client.wait_message(messages.Hello).node_kind == 1
            assert client.wait_message(messages.Heartbeat).uptime_ms < 5_000
        finally:
            client.close()
