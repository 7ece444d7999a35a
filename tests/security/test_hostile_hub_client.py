"""A hostile program on the run's machine talks to its hub: nobody but the run's owner gets in (issue 25 C1, H1-H3, M1).

A fake agent over real TCP, the run's real session and hub on loopback, tools as the `dive` commands open them.
"""

from __future__ import annotations

import os
import random
import socket
import stat
import subprocess
import threading
import time

import pytest

from groundstation.errors import CommandError, LinkError
from groundstation.links.hub_auth import HubAuthError
from groundstation.links.runs import RunInfo, announce, running
from groundstation.links.tcp import parse_host_port
from groundstation.run.hub_clients import MAX_CLIENTS, MAX_IN_FLIGHT
from groundstation.run.marker import send_marker
from protocol import FrameEncoder, StreamDecoder
from protocol import messages as m
from protocol.signing import KEY_SIZE
from tests.groundstation.fake_agent import FakeAgent
from tests.security.attack import as_another_user, attached, hub_run, tool
from tests.waiting import wait_for

HELLO = m.Hello(protocol_version=1, node_kind=2, definitions_hash=0, firmware_major=0, firmware_minor=0,
                firmware_patch=0, node_id=1, boot_id=1, name="intruder")


def _commands(agent: FakeAgent) -> list[str]:
    return [c for c in agent.executed if c not in ("PARAM_LIST", "LOG_REQUEST")]


def _intrude(address: str, payload: bytes) -> bytes:
    """Connect without the token, send `payload`, return what comes back in 1 s."""
    got = b""
    with socket.create_connection(parse_host_port(address), timeout=1.0) as sock:
        try:
            sock.sendall(payload)
            deadline = time.monotonic() + 1.0
            while time.monotonic() < deadline:
                chunk = sock.recv(65536)
                if not chunk:
                    break
                got += chunk
        except (TimeoutError, ConnectionResetError, BrokenPipeError):
            pass
    return got


def test_random_bytes_and_tokenless_frames_on_the_hub_reach_nothing(tmp_path: object) -> None:
    agent = FakeAgent()
    rng = random.Random(25)
    try:
        with hub_run(agent.url) as (session, hub, info):
            encoder = FrameEncoder()
            frames = b"".join(encoder.encode(msg).wire for msg in (
                HELLO, m.ParamSet(index=-1, value=4.2, name="z_tol_m"), m.Surface(), m.Stop(),
                m.Timesync(origin_us=2**64 - 1, receive_us=0, transmit_us=0)))
            answers = [_intrude(info.hub, frames)]
            answers += [_intrude(info.hub, rng.randbytes(65536)) for _ in range(10)]
            assert session.link_up and agent.connections == 1
            with tool() as owner:  # the owner's tool still attaches and commands
                owner.command(m.Surface())
    finally:
        agent.close()
    assert answers == [b""] * 11  # not one byte back: no HELLO, no telemetry
    assert _commands(agent) == ["CMD_SURFACE"]  # the owner's, once; none of the intruders'
    assert 2**64 - 1 not in agent.timesync_origins


def test_an_intruder_knowing_the_port_but_not_the_token_cannot_attach_as_a_tool(tmp_path: object) -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (_, _, info):
            forged = RunInfo(info.run, info.pid, info.hub, info.url, "", info.started, token="00" * 32)
            with pytest.raises(HubAuthError, match="did not prove"):
                send_marker(forged, "mine")
    finally:
        agent.close()


def test_a_squatter_on_a_dead_runs_port_is_found_out_and_learns_nothing(tmp_path: object) -> None:
    """H2: the run died (kill -9), its file stayed, and another program listens on its port (its PID alive)."""
    squatter = socket.create_server(("127.0.0.1", 0))
    received: list[bytes] = []

    def serve() -> None:
        conn, _ = squatter.accept()
        with conn:
            conn.sendall(b"0123456789abcdef0123456789abcdef " + b"0" * 64 + b"\n")  # a guess at a proof
            conn.settimeout(2.0)
            try:
                while chunk := conn.recv(65536):
                    received.append(chunk)
            except OSError:
                pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    info = RunInfo("4242", os.getpid(), f"tcp://127.0.0.1:{squatter.getsockname()[1]}", "tcp://agent:1", "", 0.0,
                   token="ab" * 32)
    announce(info)
    try:
        with pytest.raises(HubAuthError, match="not that run"):
            tool().connect()
    finally:
        squatter.close()
        thread.join(5)
    assert not info.path.exists()  # the stale announcement is withdrawn
    sent = b"".join(received)
    assert b"\x00" not in sent  # no frame: the greeting line only, nothing signed to replay later
    assert sent.count(b"\n") <= 1


def test_a_run_file_whose_pid_is_another_users_process_is_stale() -> None:
    other = subprocess.Popen(["sleep", "30"], **as_another_user()) if os.geteuid() == 0 else None
    pid = other.pid if other is not None else 1  # PID 1 belongs to root
    try:
        info = RunInfo(str(pid), pid, "tcp://127.0.0.1:9", "tcp://agent:1", "", 0.0, token="ab" * 32)
        announce(info)
        assert running() == [] and not info.path.exists()
    finally:
        if other is not None:
            other.kill()
            other.wait()


def test_announcements_are_the_owners_alone(tmp_path: object) -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (_, _, info):
            assert stat.S_IMODE(info.path.stat().st_mode) == 0o600
            assert stat.S_IMODE(info.path.parent.stat().st_mode) == 0o700
            assert info.token not in repr(info)
    finally:
        agent.close()


def test_a_command_flood_from_one_tool_neither_reaches_the_agent_nor_delays_the_owners_surface() -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (session, _, info):
            flooder = attached(info)
            encoder = FrameEncoder()
            flood = b"".join(encoder.encode(m.ParamGet(index=-1, name="z_tol_m")).wire for _ in range(20_000))
            sender = threading.Thread(target=lambda: _swallow(flooder, flood), daemon=True)
            sender.start()
            time.sleep(0.2)
            with tool() as owner:
                started = time.monotonic()
                owner.command(m.Surface(), timeout_s=5.0)  # ACKed while the flood goes on
                surfaced_s = time.monotonic() - started
            sender.join(30)
            flooder.close()
            assert session.link_up
    finally:
        agent.close()
    assert "CMD_SURFACE" in agent.executed
    # the hub refuses what is over the tool's limit itself: the agent sees a trickle, not 20 000 commands
    assert agent.executed.count("PARAM_GET") < 20_000 // 10
    assert surfaced_s < 5.0


def _swallow(sock: socket.socket, data: bytes) -> None:
    """Send `data` while reading (and dropping) the hub's BUSY answers, as a flooding tool would."""
    sock.setblocking(False)
    view = memoryview(data)
    deadline = time.monotonic() + 20
    while view and time.monotonic() < deadline:
        try:
            view = view[sock.send(view[:65536]):]
        except BlockingIOError:
            pass
        except OSError:
            return
        try:
            sock.recv(1 << 20)
        except (BlockingIOError, OSError):
            pass


def test_in_flight_commands_per_tool_are_bounded_and_refused_busy() -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (_, _, info):
            agent.ignore_commands = 1000  # the agent answers nothing now: every command stays in flight
            sock = attached(info)
            encoder, decoder = FrameEncoder(), StreamDecoder()
            sock.sendall(b"".join(encoder.encode(m.ParamGet(index=-1, name="z_tol_m")).wire for _ in range(10)))
            acks: list[m.Ack] = []
            deadline = time.monotonic() + 3
            while len(acks) < 10 - MAX_IN_FLIGHT and time.monotonic() < deadline:
                sock.settimeout(0.5)
                try:
                    acks += [f.message for f in decoder.feed(sock.recv(65536)) if isinstance(f.message, m.Ack)]
                except TimeoutError:
                    pass
            sock.close()
    finally:
        agent.close()
    assert len(acks) == 10 - MAX_IN_FLIGHT and all(a.result == 4 for a in acks)  # BUSY, from the hub


def test_connections_are_bounded_and_a_silent_one_is_closed() -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (session, hub, _):
            idle = [socket.create_connection(parse_host_port(hub.address)) for _ in range(3 * MAX_CLIENTS)]
            assert wait_for(lambda: hub.clients_served >= MAX_CLIENTS, 5)
            assert hub.client_count <= MAX_CLIENTS
            assert wait_for(lambda: hub.client_count == 0, 8)  # none proved the token in 3 s: all closed
            for sock in idle:
                sock.close()
            with tool() as owner:
                owner.command(m.ParamListRequest())
            assert session.link_up
    finally:
        agent.close()


def test_a_forged_timesync_through_the_hub_never_reaches_the_agent() -> None:
    agent = FakeAgent()
    try:
        with hub_run(agent.url) as (session, _, info):
            sock = attached(info)
            encoder, decoder = FrameEncoder(), StreamDecoder()
            sock.sendall(encoder.encode(HELLO).wire + encoder.encode(
                m.Timesync(origin_us=2**64 - 1, receive_us=0, transmit_us=0)).wire)
            answers: list[m.Timesync] = []
            assert wait_for(lambda: session.clock.synced, 5)
            deadline = time.monotonic() + 2
            sock.settimeout(0.2)
            while not answers and time.monotonic() < deadline:
                try:
                    answers += [f.message for f in decoder.feed(sock.recv(65536))
                                if isinstance(f.message, m.Timesync)]
                except TimeoutError:
                    sock.sendall(encoder.encode(m.Timesync(origin_us=2**64 - 1, receive_us=0, transmit_us=0)).wire)
            sock.close()
            assert session.stats.timesyncs_ignored == 0
    finally:
        agent.close()
    assert 2**64 - 1 not in agent.timesync_origins
    assert answers and answers[0].origin_us == 2**64 - 1 and answers[0].receive_us > 0  # answered by the hub


def test_a_keyed_runs_hub_lends_its_key_to_nobody(tmp_path: object) -> None:
    key = bytes(range(KEY_SIZE))
    agent = FakeAgent()
    try:
        with hub_run(agent.url, key=key) as _:
            with tool() as keyless, pytest.raises(CommandError, match="UNAUTHORIZED"):
                keyless.command(m.ParamSet(index=-1, value=0.2, name="z_tol_m"))
            with tool(key=bytes(KEY_SIZE)) as wrong, pytest.raises(CommandError, match="UNAUTHORIZED"):
                wrong.command(m.StartLearning(max_episodes=0))
            with tool() as keyless:  # but CMD_SURFACE needs no key (SPEC 1.2; issue 38 N9): anyone may bring it up
                keyless.command(m.Surface())
            with tool(key=key) as owner:
                owner.command(m.Surface())
    finally:
        agent.close()
    assert _commands(agent) == ["CMD_SURFACE", "CMD_SURFACE"]


def test_without_a_run_a_tool_says_so_in_one_line() -> None:
    with pytest.raises(LinkError, match="no `dive run` is running"):
        tool().connect()
