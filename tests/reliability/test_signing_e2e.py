"""Command signing end to end over TCP: a signed ground station works; unsigned, replayed and forged commands are
refused by the virtual agent, counted in HEARTBEAT.signing_rejects, and never executed; telemetry stays readable."""

from __future__ import annotations

import os
import stat
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from groundstation.links import make_link
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import LinkEvent, Received, Sent
from protocol import AckResult, FrameEncoder, Signer
from protocol import messages as m
from protocol.cobs import cobs_decode, cobs_encode
from protocol.crc import crc16_ccitt_false
from protocol.signing import parse_key, resync_nonce
from tests.simulator.agent_client import ROOT, AgentClient, running

OTHER_KEY = bytes(range(32))
DIVE_MAIN = "import sys; sys.argv[0] = 'dive'; from groundstation.cli.app import main; main()"


class SentFrames:
    """A session listener that keeps the wire bytes of every frame sent."""

    def __init__(self) -> None:
        self.sent: list[Sent] = []

    def on_received(self, received: Received) -> None:
        pass

    def on_sent(self, sent: Sent) -> None:
        self.sent.append(sent)

    def on_event(self, event: LinkEvent) -> None:
        pass


def _dive(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    """`dive ARGS` as a real process, so a traceback would show on its stderr."""
    return subprocess.run([sys.executable, "-c", DIVE_MAIN, *args], capture_output=True, text=True,
                          timeout=120, cwd=ROOT, env=env)


@pytest.fixture(scope="module")
def key_file(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("keys") / "agent.key"
    done = _dive("keygen", "--out", str(path))
    assert done.returncode == 0, done.stderr
    return path


@pytest.fixture(scope="module")
def agent(key_file: Path) -> Iterator[str]:
    with running("--tcp", "127.0.0.1:0", "--preset", "hardware", "--speed", "4", "--seed", "11",
                 "--key-file", str(key_file)) as server:
        yield server.address


def _session(address: str, key: bytes | None, **config: object) -> Session:
    options: dict[str, object] = {"reconnect": False, "backfill": False, "fetch_params": False, **config}
    return Session(make_link(address), SessionConfig(key=key, **options))  # type: ignore[arg-type]


def _flip_one_bit(wire: bytes) -> bytes:
    """The same frame with one payload bit changed and the CRC fixed, as a forger would send it."""
    body = bytearray(cobs_decode(wire[:-1])[:-2])
    body[5] ^= 0x01
    return cobs_encode(bytes(body) + crc16_ccitt_false(bytes(body)).to_bytes(2, "big")) + b"\x00"


def test_keygen_writes_a_private_hex_key_and_refuses_to_overwrite_it(key_file: Path) -> None:
    assert stat.S_IMODE(key_file.stat().st_mode) == 0o600
    assert len(parse_key(key_file.read_text())) == 32
    again = _dive("keygen", "--out", str(key_file))
    assert again.returncode == 1 and "exists" in again.stderr and "Traceback" not in again.stderr


def test_signed_commands_run_and_unsigned_replayed_forged_ones_are_refused_and_counted(
        agent: str, key_file: Path) -> None:
    key = parse_key(key_file.read_text())
    sent = SentFrames()
    with _session(agent, key) as session:
        session.add_listener(sent)
        session.connect()
        assert session.command(m.SetTarget(target_depth_m=1.25)).result == AckResult.ACCEPTED
        assert session.get_param("target_depth_m").value == 1.25  # exact in f32
    signed_set_target = next(s.wire for s in sent.sent if isinstance(s.message, m.SetTarget))

    attacker = AgentClient.tcp(agent)
    try:
        attacker.wait_message(m.Hello)
        rejects_before = attacker.wait_message(m.Heartbeat).signing_rejects
        results = [attacker.command(m.SetTarget(target_depth_m=0.3))]  # unsigned
        for wire in (signed_set_target, _flip_one_bit(signed_set_target)):  # replayed; forged
            attacker.send_raw(wire)
            results.append(attacker.wait_message(m.Ack, cmd_msg_id=m.SetTarget.MSG_ID))
        attacker.encoder = FrameEncoder(500, signer=Signer(OTHER_KEY, 3))  # signed with the wrong key
        results.append(attacker.command(m.Surface()))
        # SPEC 1.2 s. 5: the attacker's connection started a session, which emptied the ACK memory, so the exact
        # replay of an accepted command is refused by its timestamp (replayed), never given the old ACK. s. 12: a
        # CMD_SURFACE runs whatever its signature (surfacing is the fail-safe) and says so in its ACK.
        assert [a.result for a in results] == [AckResult.UNAUTHORIZED, AckResult.UNAUTHORIZED,
                                               AckResult.UNAUTHORIZED, AckResult.ACCEPTED]
        assert [a.reason.split(";")[0] for a in results[:3]] == ["signature unsigned", "signature replayed",
                                                                 "signature bad signature"]
        assert resync_nonce(results[1].reason) is not None  # a refusal for the timestamp names the re-sync nonce
        assert "without a valid signature" in results[3].reason
        heartbeat = attacker.wait_message(m.Heartbeat)
        while heartbeat.signing_rejects < rejects_before + 3:
            heartbeat = attacker.wait_message(m.Heartbeat)
        assert heartbeat.signing_rejects == rejects_before + 3
        assert attacker.of(m.Sample), "telemetry stays readable without the key"
    finally:
        attacker.close()

    with _session(agent, key) as session:  # nothing the attacker sent was executed but the fail-safe surfacing
        session.connect()
        assert session.get_param("target_depth_m").value == 1.25  # exact in f32


def test_signed_retries_over_a_lossy_link_are_not_mistaken_for_replays(key_file: Path, tmp_path: Path) -> None:
    key = parse_key(key_file.read_text())
    with running("--tcp", "127.0.0.1:0", "--preset", "hardware", "--speed", "4", "--seed", "5", "--drop", "0.1",
                 "--key-file", str(key_file), "--state-dir", str(tmp_path)) as server, \
            _session(server.address, key) as session:  # its own state: another agent than the module's
        session.connect()
        for i in range(20):
            assert session.command(m.SetTarget(target_depth_m=0.5 + i / 40)).result == AckResult.ACCEPTED
        assert session.stats.retries > 0, "the lossy link made the session retry"
        deadline = time.monotonic() + 10
        while session.last_heartbeat is None and time.monotonic() < deadline:
            time.sleep(0.05)
        first = session.last_heartbeat
        while session.last_heartbeat is first and time.monotonic() < deadline:
            time.sleep(0.05)  # a heartbeat sent after the last command
        assert session.last_heartbeat is not None and session.last_heartbeat.signing_rejects == 0


def test_dive_without_the_key_gets_one_clear_line_and_with_it_works(agent: str, key_file: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "DIVE_KEY_FILE"}
    refused = _dive("hover", agent, "0.4", env=env)
    assert refused.returncode == 1
    assert "UNAUTHORIZED" in refused.stderr and "Traceback" not in refused.stderr
    assert len(refused.stderr.strip().splitlines()) == 1
    done = _dive("hover", agent, "0.4", env={**env, "DIVE_KEY_FILE": str(key_file)})
    assert done.returncode == 0, done.stderr
    done = _dive("surface", agent, env={**env, "DIVE_KEY_FILE": str(key_file)})
    assert done.returncode == 0, done.stderr


def test_every_commanding_subcommand_signs_with_key_file(agent: str, key_file: Path) -> None:
    """Issue 13 item 7: status, params, dump, hover and surface could not sign (no --key-file); now each can."""
    env = {k: v for k, v in os.environ.items() if k != "DIVE_KEY_FILE"}
    for args in (["status", agent], ["params", agent, "get", "target_depth_m"], ["dump", agent],
                 ["hover", agent, "0.4"], ["surface", agent]):
        done = _dive(*args, "--key-file", str(key_file), env=env)
        assert done.returncode == 0 and "UNAUTHORIZED" not in done.stderr, (args, done.stderr)


def test_the_agent_refuses_to_start_with_a_bad_key_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.key"
    bad.write_text("not hex\n")
    for path in (bad, tmp_path / "missing.key"):
        done = subprocess.run([sys.executable, "-m", "simulator", "serve", "--tcp", "127.0.0.1:0", "--key-file",
                               str(path)], capture_output=True, text=True, timeout=60, cwd=ROOT)
        assert done.returncode == 2 and "key file" in done.stderr and "Traceback" not in done.stderr
        assert len(done.stderr.strip().splitlines()) == 1
