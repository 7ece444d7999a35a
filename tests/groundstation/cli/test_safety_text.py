"""Issue 13 items 7 and 8: agent text and file names are data (never Rich markup, never terminal control), the marker
file cannot stop a run, every command that talks to an agent can sign, and a key file others can read is refused."""

from __future__ import annotations

import os
import socket
import struct
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.links import make_link
from groundstation.links.hub_auth import new_token, tool_side
from groundstation.links.runs import RunInfo
from groundstation.links.tcp import parse_host_port
from groundstation.run.hub import Hub
from groundstation.run.marker import send_marker
from groundstation.safe_output import SafeConsole, one_line, printable
from groundstation.session.agent_session import Session, SessionConfig
from groundstation.session.events import EventKind, LinkEvent
from groundstation.session.keys import write_key_file
from protocol import AckResult, FrameEncoder
from protocol import messages as m
from tests.groundstation.fake_agent import FakeAgent
from tests.reliability.recordings import dive

HOSTILE = "[/]x[bold red]\x1b[2J\x1b]0;owned\x07\u202e"


def no_raw_control(text: str) -> bool:
    return "\x1b" not in text and "\x07" not in text and "\u202e" not in text


def test_printable_escapes_every_control_character_and_keeps_text() -> None:
    assert printable("tank 1, 0.5 m") == "tank 1, 0.5 m"
    assert printable(HOSTILE) == "[/]x[bold red]\\x1b[2J\\x1b]0;owned\\x07\\u202e"
    assert one_line("a\nb") == "a\\x0ab" and printable("a\nb") == "a\nb"


def test_a_safe_console_prints_markup_as_text(capsys: pytest.CaptureFixture[str]) -> None:
    SafeConsole(force_terminal=False).print(f"agent {HOSTILE}")  # a closing tag without an opening one raised
    out = capsys.readouterr().out
    assert "[/]x[bold red]" in out and no_raw_control(out)


def test_agent_text_reaches_the_terminal_as_data(fake_agent: FakeAgent) -> None:
    """`[/]` in a HELLO name or NACK reason crashed dive (Rich markup); ESC sequences reached the terminal raw."""
    fake_agent.name = HOSTILE[:24]
    fake_agent.nack_reason = HOSTILE
    shown = dive("status", fake_agent.url, timeout_s=60)
    assert shown.returncode == 0 and "[/]x[bold" in shown.stdout and no_raw_control(shown.stdout), shown.stderr
    fake_agent.refuse = int(AckResult.NOT_ALLOWED_IN_MODE)
    refused = dive("surface", fake_agent.url, timeout_s=60)
    assert refused.returncode == 1 and "Traceback" not in refused.stderr, refused.stderr
    assert "[/]x[bold red]" in refused.stderr and no_raw_control(refused.stderr)


def test_a_file_name_with_markup_and_escapes_is_printed_as_data(tmp_path: Path) -> None:
    folder = tmp_path / "[/]\x1b[31m"
    folder.mkdir(parents=True)  # the path reads "[/]": a directory "[" holding "]\x1b[31m"
    result = dive("log", "info", str(folder / "missing.mcap"))
    assert result.returncode == 1 and "[/]" in result.stderr and no_raw_control(result.stderr), result.stderr


def test_garbage_and_bad_text_on_a_runs_hub_never_stop_it(tmp_path: Path) -> None:
    """Markers reach a run through its hub now (issue 14), not a shared file: bytes that are no frame, and a TEXT
    whose bytes are no UTF-8, are dropped or shown escaped; the run and the next marker go on."""
    agent = FakeAgent()
    seen: list[str] = []
    try:
        session = Session(make_link(agent.url), SessionConfig(reconnect=False))
        session.add_listener(_Markers(seen))
        with session:
            token = new_token()
            hub = Hub(session, token).start()
            session.add_listener(hub)
            try:
                with socket.create_connection(parse_host_port(hub.address)) as sock:
                    tool_side(sock, token, "hub")  # the run's owner: garbage after the handshake
                    encoder = FrameEncoder()
                    bad_text = encoder.encode_payload(m.Text.MSG_ID, struct.pack("<QB", 0, 1) + b"\xff\xfe[x]").wire
                    sock.sendall(b"\xff\x00\x13garbage\x00" + bad_text)
                info = RunInfo("1", os.getpid(), hub.address, agent.url, "", 0.0, token=token)
                send_marker(info, "ok")
                assert session.link_up
            finally:
                hub.close()
    finally:
        agent.close()
    assert seen[-1] == "ok" and len(seen) == 2 and "\ufffd" in seen[0]  # the bad bytes shown, not obeyed


class _Markers:
    def __init__(self, seen: list[str]) -> None:
        self.seen = seen

    def on_received(self, received: object) -> None:
        pass

    def on_sent(self, sent: object) -> None:
        pass

    def on_event(self, event: LinkEvent) -> None:
        if event.kind == EventKind.MARKER:
            self.seen.append(event.detail)


@pytest.mark.parametrize("command", [["status"], ["params", "tcp://x:1"], ["surface"], ["hover", "tcp://x:1", "1"],
                                     ["dump"], ["view"], ["run"]])
def test_every_command_that_talks_to_an_agent_can_sign(command: list[str]) -> None:
    result = CliRunner().invoke(app, [command[0], "--help"])
    assert result.exit_code == 0 and "--key-file" in result.output


def test_a_key_file_others_can_read_is_refused_with_the_chmod_to_run(tmp_path: Path) -> None:
    key = write_key_file(tmp_path / "dive.key")
    os.chmod(key, 0o644)
    result = dive("status", "tcp://127.0.0.1:9", "--key-file", str(key))
    assert result.returncode == 1 and f"run: chmod 600 {key}" in result.stderr, result.stderr
    assert key.read_text().strip() not in result.stderr + result.stdout


def test_no_repr_holds_the_key_bytes(tmp_path: Path) -> None:
    from groundstation.run.job import RunConfig
    from groundstation.session.agent_session import SessionConfig
    from groundstation.session.keys import read_key_file

    key = read_key_file(write_key_file(tmp_path / "k.key"))
    shown = repr(RunConfig(session=SessionConfig(key=key)))
    assert key.hex() not in shown and repr(key) not in shown
