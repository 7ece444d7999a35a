"""Nothing but a wrong proof withdraws a run's announcement, and another user cannot lock the owner out of the hub
(issue 38 N2): a reset, a silent port or a full hub leave the file alone; other users' connections are closed at
accept (the kernel's socket table names their user), so the owner's `surface` always gets a slot."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

import pytest

from groundstation.errors import LinkError
from groundstation.links import hub as hub_link
from groundstation.links.hub_auth import HubFullError
from groundstation.links.runs import RunInfo, announce
from groundstation.run.hub_clients import MAX_CLIENTS
from groundstation.session import control
from tests.groundstation.fake_agent import FakeAgent
from tests.security.attack import as_another_user, attached, hub_run, tool

SYSTEM_PYTHON = shutil.which("python3", path="/usr/bin:/bin")


@contextmanager
def fake_hub(answer: Callable[[socket.socket], None]) -> Iterator[RunInfo]:
    """A live run's announcement (this process's PID) whose port answers the handshake with `answer`."""
    server = socket.create_server(("127.0.0.1", 0))
    stop = threading.Event()

    def serve() -> None:
        server.settimeout(0.2)
        while not stop.is_set():
            try:
                conn, _ = server.accept()
            except OSError:
                continue
            with conn:
                answer(conn)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    info = RunInfo("4343", os.getpid(), f"tcp://127.0.0.1:{server.getsockname()[1]}", "tcp://agent:1", "", 0.0,
                   token="ab" * 32)
    announce(info)
    try:
        yield info
    finally:
        stop.set()
        thread.join(5)
        server.close()


def _reset(conn: socket.socket) -> None:
    conn.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\1\0\0\0\0\0\0\0")  # close with RST


def _silent(conn: socket.socket) -> None:
    time.sleep(3.5)  # past the tool's 3 s handshake timeout


def _full(conn: socket.socket) -> None:
    conn.sendall(b"DIVE-HUB/1 FULL\n")


@pytest.mark.parametrize("answer", [_reset, _silent, _full], ids=["reset", "timeout", "full"])
def test_a_handshake_failing_without_a_wrong_proof_leaves_the_announcement(
        answer: Callable[[socket.socket], None], monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hub_link, "FULL_RETRY_S", 0.05)
    with fake_hub(answer) as info:
        with pytest.raises(LinkError):  # HubAuthError, or a reset before the handshake began
            tool().connect()
        assert info.path.exists()  # the run is alive: its owner's next `dive surface` still finds it


def test_a_full_hub_says_so_in_one_line_and_is_asked_again(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(hub_link, "FULL_RETRY_S", 0.05)
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (_, hub, info):
            held = [attached(info) for _ in range(MAX_CLIENTS)]  # the owner's own tools, every slot
            with pytest.raises(HubFullError) as refused:
                tool().connect()
            assert "is full" in str(refused.value) and "\n" not in str(refused.value)
            assert info.path.exists()
            held.pop().close()  # one tool ends: the next attach gets its slot
            with tool() as s:
                assert control.surface(s).accepted
            for sock in held:
                sock.close()
    finally:
        agent.close()


@pytest.mark.skipif(os.geteuid() != 0 or SYSTEM_PYTHON is None,
                    reason="needs root and a system python3 to act as another local user (nobody)")
def test_another_users_connections_cannot_lock_the_owner_out() -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (_, hub, info):
            port = info.hub.rsplit(":", 1)[1]
            hold = ("import socket, time\nheld = []\nend = time.monotonic() + 6\nwhile time.monotonic() < end:\n"
                    f"    try: held.append(socket.create_connection(('127.0.0.1', {port}), timeout=1))\n"
                    "    except OSError: pass\n    held = held[-64:]\n    time.sleep(0.01)\n")
            squatter = subprocess.Popen([SYSTEM_PYTHON or "python3", "-c", hold], cwd="/", **as_another_user())
            try:
                time.sleep(1.0)  # its connections are in (on the old hub: every slot, again and again)
                with tool() as s:
                    answer = control.surface(s)
            finally:
                squatter.kill()
                squatter.wait(10)
            assert answer.accepted, answer  # (its time is the A/B benchmark's figure, not a test's)
            assert info.path.exists()
            assert hub.refused_users > 0
    finally:
        agent.close()
