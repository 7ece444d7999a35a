"""`dive replay` from a user's side: truncated files, bad input, and the web viewer mode."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import urllib.request
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from tests.groundstation.rrd_readback import rows_per_entity
from tests.groundstation.synthetic_agent import Traffic, generate, record
from tests.listening import listening_addresses, other_local_addresses

DIVE = str(Path(sys.executable).with_name("dive"))


@pytest.fixture(scope="module")
def traffic() -> Traffic:
    return generate(duration_s=30.0)


@pytest.fixture(scope="module")
def small_recording(traffic: Traffic, tmp_path_factory: pytest.TempPathFactory) -> Path:
    # flush_period_s=0 closes a chunk after every message, as a long run's 1 s flushes would
    return record(traffic, tmp_path_factory.mktemp("rec") / "small.mcap", flush_period_s=0.0)


def _dive(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([DIVE, *args], capture_output=True, text=True,
                          timeout=60, check=False)


def test_a_recording_cut_short_by_a_crash_replays_what_was_complete(
    traffic: Traffic, small_recording: Path, tmp_path: Path
) -> None:
    cut = tmp_path / "crashed.mcap"
    data = small_recording.read_bytes()
    cut.write_bytes(data[: int(len(data) * 0.6)])
    result = CliRunner().invoke(app, ["replay", str(cut), "--rrd", str(tmp_path / "cut.rrd")])
    assert result.exit_code == 0, result.output
    assert "cut short" in result.output
    shown = rows_per_entity(tmp_path / "cut.rrd")["/depth/z_up_m"]
    assert 0.4 * traffic.samples < shown < traffic.samples


@pytest.mark.parametrize(
    ("content", "message"),
    [(None, "no such recording"), (b"", "not an MCAP"), (b"PK\x03\x04 a zip, not a recording" * 40, "not an MCAP")],
)
def test_bad_input_gives_one_clear_line_and_a_non_zero_exit(
    content: bytes | None, message: str, tmp_path: Path
) -> None:
    path = tmp_path / "input.mcap"
    if content is not None:
        path.write_bytes(content)
    result = _dive("replay", str(path), "--rrd", str(tmp_path / "out.rrd"))
    assert result.returncode == 1
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], result.stderr
    assert "Traceback" not in result.stderr


def test_bad_options_give_one_clear_line(small_recording: Path) -> None:
    for option in (["--speed", "fast"], ["--from", "yesterday"]):
        result = _dive("replay", str(small_recording), "--viewer", "none", *option)
        assert result.returncode == 2 and len(result.stderr.strip().splitlines()) == 1, result.stderr  # usage


def test_a_replay_shown_nowhere_says_what_it_read(small_recording: Path) -> None:
    """--viewer none without --rrd reads the recording through (a check that it reads) and says so in one line."""
    result = _dive("replay", str(small_recording), "--viewer", "none")
    assert result.returncode == 0, result.stderr
    read = re.search(r"^read (\d+) frames of .* shows them nowhere", result.stdout, re.MULTILINE)
    assert read is not None and int(read.group(1)) > 0, result.stdout


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _answers(address: str, port: int) -> bool:
    with socket.socket() as s:
        s.settimeout(2.0)
        return s.connect_ex((address, port)) == 0


def test_web_viewer_mode_answers_http_on_loopback_only_and_stops_cleanly(small_recording: Path) -> None:
    """Both servers of --viewer web (the page and the data stream) listen on 127.0.0.1 and on no other address of
    this machine (issue 25 L4: rerun-sdk's serve_web_viewer listened on all interfaces)."""
    web_port, grpc_port = _free_port(), _free_port()
    process = subprocess.Popen(
        [DIVE, "replay", str(small_recording), "--viewer", "web",
         "--web-port", str(web_port), "--grpc-port", str(grpc_port)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env={**os.environ, "DISPLAY": ""},
    )
    try:
        assert process.stdout is not None
        line = process.stdout.readline()
        assert line.startswith(f"Rerun web viewer: http://127.0.0.1:{web_port}/"), line
        with urllib.request.urlopen(f"http://127.0.0.1:{web_port}/", timeout=20) as response:
            assert response.status == 200
            assert b"<html" in response.read().lower()
        for port in (web_port, grpc_port):
            assert listening_addresses(port) == {"127.0.0.1"}, port
            for other in other_local_addresses():  # where the machine has one: not answered there
                assert not _answers(other, port), f"{other}:{port} answers"
        process.send_signal(signal.SIGTERM)
        assert process.wait(timeout=20) == 130  # stopped as by Ctrl-C, after a clean shutdown
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    with socket.socket() as s, pytest.raises(ConnectionRefusedError):  # nothing listens there any more
        s.connect(("127.0.0.1", web_port))
