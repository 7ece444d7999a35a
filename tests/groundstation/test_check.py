"""`dive check` against real agent processes: `dive sim` over TCP and a pty passes; a broken agent fails, by section.

Each agent process runs the whole suite once (not once per check): the suite is the expensive part.
"""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest

from groundstation.keys import write_key_file
from tests.reliability.recordings import DIVE_MAIN, ROOT

BROKEN_AGENT = Path(__file__).with_name("broken_agent.py")
START_TIMEOUT_S = 90.0  # the first start of a virtual agent compiles its numba kernels


@contextmanager
def agent(tmp_path: Path, *args: str, script: list[str] | None = None) -> Iterator[str]:
    """A virtual agent process (`dive sim`, or the broken one) at full speed; yields what to connect to."""
    # At full speed hours of agent time pass in seconds: keep the simulated battery from running flat mid-run.
    params = tmp_path / "agent.toml"
    params.write_text("low_batt_v = 3.0\n")
    command = script or ["-c", DIVE_MAIN, "sim"]
    proc = subprocess.Popen([sys.executable, *command, "--speed", "max", "--params", str(params), *args],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)
    try:
        assert proc.stdout is not None
        address = proc.stdout.readline().strip()
        assert address, proc.stderr.read() if proc.stderr else "no address"
        yield address
    finally:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def check(url: str, *args: str) -> tuple[int, dict[str, Any]]:
    done = subprocess.run([sys.executable, "-c", DIVE_MAIN, "check", url, "--json", *args], capture_output=True,
                          text=True, timeout=240, cwd=ROOT)
    assert "Traceback" not in done.stderr, done.stderr
    return done.returncode, json.loads(done.stdout)


def by_result(report: dict[str, Any], result: str) -> list[str]:
    return [f"{c['id']}: {c['detail']}" for c in report["checks"] if c["result"] == result]


@pytest.mark.slow
@pytest.mark.parametrize(("transport", "preset", "signed"), [("tcp", "paper", False), ("pty", "hardware", True)],
                         ids=["tcp-paper-unsigned", "pty-hardware-signed"])
def test_dive_sim_conforms(tmp_path: Path, transport: str, preset: str, signed: bool) -> None:
    key_args = []
    if signed:
        key = write_key_file(tmp_path / "dive.key")
        key_args = ["--key-file", str(key)]
    where = ["--tcp", "127.0.0.1:0"] if transport == "tcp" else ["--pty"]
    with agent(tmp_path, *where, "--preset", preset, "--seed", "3", *key_args) as url:
        code, report = check(url, "--allow-motion", *key_args)
    assert by_result(report, "FAIL") == [], report
    assert code == 0
    skipped = by_result(report, "SKIP")
    # Every check ran: signing ones with the key; a bound or overwritten log only when the log is long enough.
    assert all(s.startswith(("log.bound_512", "log.gone")) for s in skipped), skipped
    assert report["counts"]["PASS"] >= 60


@pytest.mark.slow
def test_a_broken_agent_fails_in_the_right_sections(tmp_path: Path) -> None:
    script = [str(BROKEN_AGENT), "unknown-no-ack,rejects-as-frames", "serve"]
    with agent(tmp_path, "--tcp", "127.0.0.1:0", script=script) as url:
        code, report = check(url, "--only", "ack", "--only", "junk.crc_error", "--only", "junk.runt",
                             "--timeout", "0.5")
    assert code == 1
    failed = {c["id"]: c for c in report["checks"] if c["result"] == "FAIL"}
    assert set(failed) == {"ack.unknown_command", "junk.crc_error", "junk.runt"}, report
    assert failed["ack.unknown_command"]["section"].startswith("5 Commands")
    assert "no ACK" in failed["ack.unknown_command"]["detail"]
    assert failed["junk.crc_error"]["section"].startswith("1 Frame")
    assert "rx_rejects +0 (wanted +1)" in failed["junk.crc_error"]["detail"]
    assert "rx_frames" in failed["junk.runt"]["detail"]
    assert all(c["result"] == "PASS" for c in report["checks"] if c["id"] not in failed)
    assert failed["ack.unknown_command"]["sentence"]  # the spec sentence it tests is in the report


def test_a_dead_link_is_one_line_and_exit_1() -> None:
    done = subprocess.run([sys.executable, "-c", DIVE_MAIN, "check", "tcp://127.0.0.1:1"], capture_output=True,
                          text=True, timeout=60, cwd=ROOT)
    assert done.returncode == 1
    assert "Traceback" not in done.stderr
    assert done.stderr.strip().startswith("dive:") and len(done.stderr.strip().splitlines()) == 1


def test_bad_options_are_usage_errors() -> None:
    for args in (["--timeout", "0"], ["--param", "low_batt_v"], ["--only", "no_such_check"]):
        done = subprocess.run([sys.executable, "-c", DIVE_MAIN, "check", "tcp://127.0.0.1:1", *args],
                              capture_output=True, text=True, timeout=60, cwd=ROOT)
        assert done.returncode == 2, (args, done.stderr)
        assert "Traceback" not in done.stderr
