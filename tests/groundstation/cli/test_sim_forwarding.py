"""`dive sim` as a user types it: it serves the virtual agent (TCP and pty) and its help names `dive sim`."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest

from protocol import messages
from tests.reliability.recordings import DIVE_MAIN, ROOT, dive
from tests.simulator.agent_client import AgentClient


def test_the_help_names_the_command_the_user_typed() -> None:
    for command in ("sim", "study", "fit"):
        done = dive(command, "--help")
        assert done.returncode == 0, done.stderr
        assert f"Usage: dive {command} [OPTIONS]" in done.stdout


@pytest.mark.parametrize("transport", ["--tcp", "--pty"])
def test_dive_sim_serves_an_agent_that_says_hello_first(transport: str) -> None:
    where = ["--tcp", "127.0.0.1:0"] if transport == "--tcp" else ["--pty"]
    proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "sim", *where, "--seed", "1"],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert proc.stdout is not None
        first_line = proc.stdout.readline().strip()  # what to connect to, on the first line
        client = AgentClient.tcp(first_line) if transport == "--tcp" else AgentClient.pty(first_line)
        try:
            hello = client.wait_message(messages.Hello)
            assert hello.name
        finally:
            client.close()
    finally:
        proc.send_signal(signal.SIGTERM)
        assert proc.wait(timeout=10) == 0


def test_an_interrupt_sent_to_dive_alone_stops_the_agent_too() -> None:
    proc = subprocess.Popen([sys.executable, "-c", DIVE_MAIN, "sim", "--tcp", "127.0.0.1:0"],
                            stdout=subprocess.PIPE, text=True, cwd=ROOT)
    assert proc.stdout is not None
    address = proc.stdout.readline().strip()
    proc.send_signal(signal.SIGINT)
    assert proc.wait(timeout=15) in (0, 130)
    with pytest.raises(OSError):  # nobody listens there any more
        AgentClient.tcp(address).close()
