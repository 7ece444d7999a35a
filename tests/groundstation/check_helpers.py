"""`dive check` in tests: a virtual agent process (`dive sim` or the broken agent) and the check run against it."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from typer.testing import CliRunner

from groundstation.cli.app import app
from tests.reliability.recordings import DIVE_MAIN, ROOT

BROKEN_AGENT = Path(__file__).resolve().parent / "broken_agent.py"


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
    """`dive check URL --json ARGS`, in this process (importing the CLI takes seconds; the agent is a process)."""
    result = CliRunner().invoke(app, ["check", url, "--json", *args])
    assert result.exception is None or isinstance(result.exception, SystemExit), result.exception
    return result.exit_code, json.loads(result.stdout)


def by_result(report: dict[str, Any], result: str) -> list[str]:
    """The checks of a `dive check --json` report that ended in RESULT, each as "id: detail"."""
    return [f"{c['id']}: {c['detail']}" for c in report["checks"] if c["result"] == result]
