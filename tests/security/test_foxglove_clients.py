"""No Foxglove client starves the recording or eats the run's memory, and the operator can tell their server from
an impostor (issue 38 N3, N4, N5): the real server, its door and real WebSocket clients on loopback."""

from __future__ import annotations

import functools
import json
import os
import shutil
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pytest

from groundstation.cli.validate import UsageError
from groundstation.session.events import EventKind, LinkEvent
from groundstation.session.handoff import Handoff
from groundstation.view.foxglove import live as live_module
from groundstation.view.foxglove.gate import MAX_CLIENTS
from groundstation.view.foxglove.live import FoxgloveLive
from tests.groundstation.foxglove_client import FoxgloveClient
from tests.security.attack import as_another_user
from tests.security.foxglove_intruder import Client

SAMPLE = "/agent/SAMPLE"
SYSTEM_PYTHON = shutil.which("python3", path="/usr/bin:/bin")


def _body(i: int) -> bytes:
    return json.dumps({"sample": i, "depth_m": i / 1000, "mode": "LEARNING", "pad": "x" * 200}).encode()


def _kept(live: FoxgloveLive, topic: str, count: int) -> None:
    channel = live.channels.channel(topic, "diving_agent.T", {"type": "object"})
    now = time.time_ns()
    for i in range(count):
        live.channels._send(channel, topic, now + i, functools.partial(_body, i))


def test_a_history_being_sent_holds_up_neither_the_session_nor_the_publisher() -> None:
    """N3: a subscription's history (10 000 messages, 0.3 s of JSON) was sent holding the lock every frame needs,
    on the session's reader thread. Now the session hands frames over and goes on, and the publisher is not held."""
    live = FoxgloveLive(0, "test")
    try:
        _kept(live, SAMPLE, 100)
        stuck, release = threading.Event(), threading.Event()

        def slow() -> bytes:
            stuck.set()
            release.wait(10)
            return b"{}"

        channel = live.channels.channel(SAMPLE, "diving_agent.T", {"type": "object"})
        live.channels._send(channel, SAMPLE, time.time_ns(), slow)  # a body whose encoding takes long
        replay = threading.Thread(target=live.channels.subscribed, args=(SAMPLE, 7), daemon=True)
        replay.start()
        assert stuck.wait(5)
        published = threading.Thread(target=live.channels.on_event,
                                     args=(LinkEvent(EventKind.ERROR, time.time_ns(), "x"),), daemon=True)
        published.start()
        published.join(3)
        not_held = not published.is_alive()
        release.set()
        replay.join(5)
        assert not_held, "publishing waited for a history being encoded and sent"

        # the session's side: a listener that blocks costs it nothing, what does not fit is dropped and counted
        blocked = threading.Event()
        handoff = Handoff(live.channels, 10, "test")
        handoff.listener = type("Blocking", (), {"on_event": lambda self, e: blocked.wait(10)})()  # type: ignore
        began = time.monotonic()
        for _ in range(100):
            handoff.on_event(LinkEvent(EventKind.ERROR, time.time_ns(), "x"))
        assert time.monotonic() - began < 1.0 and handoff.dropped >= 89
        blocked.set()
        handoff.close()
    finally:
        live.close()


def test_a_flapping_subscription_queues_no_histories() -> None:
    """N3: each subscribe of a flapping client queued a replay of the whole history; 15 s of flapping queued 25 min.
    Now a client's subscriptions are coalesced: after 300 flaps another client's subscription is served at once."""
    live = FoxgloveLive(0, "test")
    try:
        _kept(live, SAMPLE, 10_000)
        _kept(live, "/agent/HEARTBEAT", 10)
        with FoxgloveClient.connected(live.port) as flapper, FoxgloveClient.connected(live.port) as other:
            assert flapper.pump(lambda: SAMPLE in flapper.channels, 5) and other.pump(lambda: SAMPLE in other.channels)
            channel = flapper.channels[SAMPLE]["id"]
            for i in range(300):
                flapper.ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": i, "channelId": channel}]}))
                flapper.ws.send(json.dumps({"op": "unsubscribe", "subscriptionIds": [i]}))
            flapper.ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 999, "channelId": channel}]}))
            beats = other.subscribe("/agent/HEARTBEAT")
            assert other.pump(lambda: len(other.messages.get(beats, [])) == 10, 10), "queued behind the flaps"
            assert flapper.pump(lambda: len(flapper.messages.get(999, [])) == 10_000, 10)  # its last one, whole
    finally:
        live.close()


def _slow_reader(port: int) -> Client:
    """A client that subscribes to the samples and never reads (its socket's buffers as small as they go)."""
    client = Client(port)
    if client.upgraded:
        client.sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
        for opcode, payload in client.frames(0.5):
            if opcode == 1 and json.loads(payload)["op"] == "advertise":
                ids = [c["id"] for c in json.loads(payload)["channels"] if c["topic"] == SAMPLE]
                client.send_json({"op": "subscribe", "subscriptions": [{"id": 1, "channelId": ids[0]}]})
    return client


def test_slow_readers_are_bounded_in_number_and_each_in_its_queue() -> None:
    """N4: 40 clients that never read grew a run by 1 GB, and there was no client limit. Now at most MAX_CLIENTS
    are let through (the rest: 503), and one that does not read is dropped once its queue is full."""
    live = FoxgloveLive(0, "test")
    readers: list[Client] = []
    try:
        _kept(live, SAMPLE, 10)
        readers = [_slow_reader(live.port) for _ in range(MAX_CLIENTS + 4)]
        through = [r for r in readers if r.upgraded]
        assert len(through) == MAX_CLIENTS, [r.status for r in readers]
        assert all("503" in r.status for r in readers if not r.upgraded)
        channel = live.channels.channel(SAMPLE, "diving_agent.T", {"type": "object"})
        body = b"x" * 60_000
        for _ in range(40):  # 2.4 MB a client: more than its queue holds, with what the kernel holds
            for _ in range(10):
                live.channels._send(channel, SAMPLE, time.time_ns(), functools.partial(bytes, body))
            time.sleep(0.05)
        deadline = time.monotonic() + 10
        while live.gate.counts.dropped_slow < MAX_CLIENTS and time.monotonic() < deadline:
            for _ in range(10):
                live.channels._send(channel, SAMPLE, time.time_ns(), functools.partial(bytes, body))
            time.sleep(0.05)
        assert live.gate.counts.dropped_slow == MAX_CLIENTS, live.gate.counts
        said = live.refusals()  # the run's last line about its Foxglove clients
        assert f"{MAX_CLIENTS} clients dropped for not reading" in said and "4 refused as too many" in said, said
    finally:
        for reader in readers:
            reader.sock.close()
        live.close()


def test_a_taken_default_port_is_an_error_and_the_server_names_itself(monkeypatch: pytest.MonkeyPatch,
                                                                      capsys: pytest.CaptureFixture[str]) -> None:
    """N5: another user who bound 8765 first got the operator (the run moved to a free port, the app connected to
    the impostor). Now the default port taken is one line and exit 2; the printed #tag is in the server's name."""
    from groundstation.cli.live_views import open_foxglove

    code = ("import socket, sys, time\ns = socket.create_server(('127.0.0.1', 0))\nprint(s.getsockname()[1], "
            "flush=True)\ntime.sleep(30)\n")
    other_user = os.geteuid() == 0 and SYSTEM_PYTHON is not None  # else this user plays the impostor
    python = (SYSTEM_PYTHON or sys.executable) if other_user else sys.executable
    impostor = subprocess.Popen([python, "-c", code], cwd="/", stdout=subprocess.PIPE, text=True,
                                **(as_another_user() if other_user else {}))
    try:
        assert impostor.stdout is not None
        taken = int(impostor.stdout.readline())
        monkeypatch.setattr(live_module, "DEFAULT_PORT", taken)  # the test's own port, never the real 8765
        with pytest.raises(UsageError, match=f"port {taken} is in use"):
            open_foxglove(taken, "test").close()
    finally:
        impostor.kill()
        impostor.wait(10)
    live = open_foxglove(0, "dive run sim://")
    try:
        said = capsys.readouterr().err
        tag = said.split("server name ends #", 1)[1].split(";")[0]
        with FoxgloveClient.connected(live.port) as fox:
            assert fox.pump(lambda: bool(fox.server_info), 5)
            assert fox.server_info["name"] == f"dive run sim:// #{tag}"
    finally:
        live.close()


def test_clients_that_vanish_print_nothing_on_the_runs_terminal() -> None:
    """The SDK printed a line per WebSocket client that went away untidily ("Error receiving from client ...") onto
    the run's terminal: hundreds in a flood. Now none, whichever port they tore down."""
    serve = ("import sys\nfrom groundstation.view.foxglove.live import FoxgloveLive\n"
             "live = FoxgloveLive(0, 't')\nprint(live.port, live.server.port, flush=True)\n"
             "sys.stdin.readline()\nlive.close()\n")
    root = Path(__file__).resolve().parents[2]
    server = subprocess.Popen([sys.executable, "-c", serve], cwd=root, env={**os.environ, "PYTHONPATH": str(root)},
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert server.stdout is not None and server.stdin is not None
        ports = [int(port) for port in server.stdout.readline().split()]
        assert len(ports) == 2, server.stderr.read() if server.stderr else ""
        for port in ports:
            for _ in range(20):
                client = Client(port)
                client.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\1\0\0\0\0\0\0\0")  # a reset
                client.sock.sendall(b"\x82\x05ab")  # and a frame torn off
                client.sock.close()
        time.sleep(0.5)
        _, said = server.communicate("\n", timeout=30)
    finally:
        if server.poll() is None:
            server.kill()
            server.wait(10)
    assert server.returncode == 0 and said == "", said[-2000:]


def test_where_the_kernel_cannot_name_a_peer_the_printed_secret_path_is_the_key(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """N1 on a machine without /proc/net/tcp (macOS): the door lets through only a client that asks for the run's
    secret path, which the address printed to the owner carries."""
    from groundstation.view.foxglove import gate

    monkeypatch.setattr(gate, "peer_is_owner", lambda sock: None)
    monkeypatch.setattr(live_module, "table_readable", lambda: False)
    live = FoxgloveLive(0, "test")
    try:
        assert live.address == f"ws://127.0.0.1:{live.port}/{live.gate.token}"
        guess = Client(live.port)  # the bare port, as a guess
        assert "403" in guess.status, guess.status
        guess.sock.close()
        with FoxgloveClient.connected(live.port, path=f"/{live.gate.token}") as owner:
            assert owner.pump(lambda: bool(owner.server_info), 5)
    finally:
        live.close()


def test_dump_images_go_to_the_owners_subscribed_clients_alone() -> None:
    """N1: the value and policy images were broadcast to every subscriber; now each goes to the clients that came
    through the door and subscribed, and a client at the SDK's own port behind it gets none."""
    import struct

    from groundstation.session.dumps import Dump
    from groundstation.view.foxglove.images import POLICY_TOPIC
    from protocol import DumpKind

    live = FoxgloveLive(0, "test")
    try:
        with FoxgloveClient.connected(live.port) as owner, FoxgloveClient.connected(live.server.port) as behind:
            assert owner.pump(lambda: POLICY_TOPIC in owner.channels) and behind.pump(lambda: POLICY_TOPIC in
                                                                                     behind.channels)
            mine, theirs = owner.subscribe(POLICY_TOPIC), behind.subscribe(POLICY_TOPIC)
            time.sleep(0.5)  # the subscriptions reach the server
            live.channels.publish_dump(Dump(1, DumpKind.VALUES, 7, struct.pack("<101f", *range(101))), time.time_ns())
            live.channels.publish_dump(Dump(2, DumpKind.POLICY, 7, bytes([0, 1, 255] * 33 + [0, 0])), time.time_ns())
            assert owner.pump(lambda: len(owner.messages.get(mine, [])) == 1, 5)
            behind.pump(lambda: False, 1.0)
            assert behind.messages.get(theirs, []) == []
    finally:
        live.close()
