"""What reaches the terminal when something fails where no check caught it (issue 25 L2): one line, no literal colour
tags, and a reason for what hostile data raises (RecursionError, OverflowError)."""

from __future__ import annotations

import subprocess
import sys

import pytest

_RAISE = """
import sys
from groundstation.cli import app as cli
def boom():
    raise {error}
cli.app = boom
cli.main()
"""


@pytest.mark.parametrize(("error", "said"), [
    ("ValueError('[red]bad[/] \\\\x1b[31m')", "dive: internal error: ValueError: [red]bad[/]"),
    ("RecursionError('maximum recursion depth exceeded')", "dive: the data is nested too deeply to read"),
    ("OverflowError('int too large to convert')", "dive: a number in the data is out of range"),
])
def test_an_unexpected_error_is_one_plain_line(error: str, said: str) -> None:
    done = subprocess.run([sys.executable, "-c", _RAISE.format(error=error)], capture_output=True, text=True,
                          timeout=60)
    lines = [line for line in done.stderr.splitlines() if line.strip()]
    assert done.returncode == 1 and len(lines) == 1 and lines[0].startswith(said), done.stderr
    assert "[bold red]" not in done.stderr and "\x1b" not in done.stderr and "Traceback" not in done.stderr
