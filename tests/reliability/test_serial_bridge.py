"""The ESP8266 bridge for real: the virtual agent on a pty, socat bridging it to TCP, `dive run` over TCP."""

from __future__ import annotations

import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.reliability.recordings import assert_complete, dive, read
from tests.simulator.agent_client import running

SOCAT = shutil.which("socat")
pytestmark = pytest.mark.skipif(SOCAT is None, reason="socat not found: apt-get install socat")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _listening(port: int) -> bool:
    """True once something listens on 127.0.0.1:port (read from /proc, so no probe connection opens the pty)."""
    needle = f"0100007F:{port:04X}"
    for table in ("/proc/net/tcp",):
        for line in Path(table).read_text().splitlines()[1:]:
            parts = line.split()
            if parts[1] == needle and parts[3] == "0A":
                return True
    return False


@pytest.fixture
def bridge() -> Iterator[str]:
    """socat between a TCP port and the agent's pty, like the ESP8266 between Wi-Fi and the Teensy's UART."""
    assert SOCAT is not None
    with running("--pty", "--preset", "hardware", "--speed", "50", "--seed", "3") as agent:
        port = _free_port()
        socat = subprocess.Popen([SOCAT, f"TCP-LISTEN:{port},bind=127.0.0.1,reuseaddr,fork",
                                  f"FILE:{agent.address},raw,echo=0"], stderr=subprocess.DEVNULL)
        try:
            deadline = time.monotonic() + 10
            while not _listening(port):
                assert time.monotonic() < deadline and socat.poll() is None, "socat did not start listening"
                time.sleep(0.05)
            yield f"tcp://127.0.0.1:{port}"
        finally:
            socat.terminate()
            socat.wait(10)


@pytest.mark.slow
def test_dive_run_over_a_socat_serial_bridge_records_a_complete_readable_file(bridge: str, tmp_path: Path) -> None:
    done = dive("run", bridge, "--episodes", "2", "--out", str(tmp_path))
    assert done.returncode == 0, done.stderr
    files = sorted(tmp_path.glob("*.mcap"))
    assert len(files) == 1 and str(files[0]) in done.stdout.replace("\n", "")  # rich wraps long lines
    rec = read(files[0])
    assert len(rec.samples) > 100
    assert_complete(rec, episodes=2)
    info = dive("log", "info", str(files[0]))
    assert info.returncode == 0 and "Traceback" not in info.stderr
