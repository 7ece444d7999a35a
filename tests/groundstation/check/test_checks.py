"""`dive check` against real agent processes: `dive sim` over TCP and a pty passes; a broken agent fails, by section.

Each agent process runs the whole suite once (not once per check): the suite is the expensive part.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
from typer.testing import CliRunner

from groundstation.cli.app import app
from groundstation.session.keys import write_key_file
from tests.groundstation.check_helpers import BROKEN_AGENT, agent, by_result, check
from tests.reliability.recordings import ROOT


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
        # A virtual agent compiles some kernels on first use, taking seconds on a loaded machine: a longer wait.
        code, report = check(url, "--allow-motion", "--timeout", "10", *key_args)
    assert by_result(report, "FAIL") == [], report
    assert code == 0
    skipped = [c["id"] for c in report["checks"] if c["result"] == "SKIP" and not (c["requires_key"] and not signed)]
    # Every check ran (the signing ones when there is a key), but those that need a long log to be meaningful
    # (and over a pty the link-taken check, which needs a second TCP connection).
    assert set(skipped) <= {"log.bound_512", "log.gone", *(["link.taken"] if transport == "pty" else [])}, skipped
    print(f"{transport} {preset} signed={signed}: {report['counts']} in {report['seconds']} s")
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
    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        url = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    result = CliRunner().invoke(app, ["check", url])
    assert result.exit_code == 1
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("dive:") and "cannot connect" in lines[0], result.stderr


def test_a_link_that_dies_mid_run_ends_it_with_exit_1() -> None:
    """An agent that hangs up after the connect: the check in progress fails naming the link, the rest are not run."""
    with socket.create_server(("127.0.0.1", 0)) as server:
        url = f"tcp://127.0.0.1:{server.getsockname()[1]}"
        hang_up = threading.Thread(target=lambda: server.accept()[0].close(), daemon=True)
        hang_up.start()
        code, report = check(url, "--only", "handshake", "--only", "junk")
        hang_up.join(5)
    assert code == 1
    assert report["aborted"].startswith("link: ")
    assert all(c["result"] == "FAIL" for c in report["checks"])
    assert report["checks"][-1]["detail"].startswith("not run: link: ")


def test_bad_options_are_usage_errors() -> None:
    for args in (["--timeout", "0"], ["--param", "low_batt_v"], ["--only", "no_such_check"]):
        result = CliRunner().invoke(app, ["check", "tcp://127.0.0.1:1", *args])
        assert result.exit_code == 2, (args, result.output)


def test_the_run_order_is_the_modules_order_whatever_was_imported_first() -> None:
    """The handshake checks run first (they need a link nothing was sent on yet), even when another check module
    was imported before the runner, as a test that uses one check does."""
    script = ("import groundstation.check.linkloss\n"
              "from groundstation.check.runner import CHECK_MODULES, selected\n"
              "modules = [c.run.__module__.rsplit('.', 1)[-1] for c in selected(())]\n"
              "print(modules[0], modules == sorted(modules, key=CHECK_MODULES.index))\n")
    result = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, cwd=ROOT, check=True)
    assert result.stdout.split() == ["handshake", "True"]
