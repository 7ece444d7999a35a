"""The run pane on a real terminal (issue 40 item 1): a `dive run` in a pseudo-terminal, the operator's tools in
other "panes" (child processes attached to its hub); every command echoed with who sent it, the held time and the
target on the status line, a depth alarm's flag through acknowledge (`dive ack` and the key `a`) and clear, and
the line Ctrl-C leaves; `dive status` from another pane shows the run's alarm flag as the pane does."""

from __future__ import annotations

import fcntl
import os
import pty
import re
import struct
import subprocess
import termios
import threading
import time
from pathlib import Path

import pytest

from tests.groundstation.hub_helpers import DIVE, dive, dive_env

pytestmark = pytest.mark.slow

ANSI = re.compile(r"\x1b\[[0-9;?]*[A-Za-z]|\x1b\][^\x07]*\x07")


def _controlling_terminal() -> None:
    fcntl.ioctl(0, termios.TIOCSCTTY, 0)


class Pane:
    """`dive run` on the secondary side of a pty 200 columns wide; everything it writes, kept as text."""

    def __init__(self, args: list[str], env: dict[str, str]) -> None:
        self.primary, secondary = pty.openpty()
        fcntl.ioctl(secondary, termios.TIOCSWINSZ, struct.pack("HHHH", 50, 200, 0, 0))
        # A session of its own whose controlling terminal the pty is, as a shell's job: Ctrl-C typed is a SIGINT,
        # and the run is the terminal's foreground job (it reads its keys only then)
        self.proc = subprocess.Popen(args, env=env, stdin=secondary, stdout=secondary, stderr=secondary,
                                     start_new_session=True, preexec_fn=_controlling_terminal)
        os.close(secondary)
        self._seen = bytearray()
        self._lock = threading.Lock()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self) -> None:
        while True:
            try:
                chunk = os.read(self.primary, 65536)
            except OSError:
                return
            if not chunk:
                return
            with self._lock:
                self._seen += chunk

    @property
    def text(self) -> str:
        with self._lock:
            return ANSI.sub("", self._seen.decode(errors="replace"))

    def wait_for(self, pattern: str, after: int = 0, timeout_s: float = 90.0) -> int:
        """Where `pattern` (a regex) first shows at or past `after` in the pane's text; fails with the text."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            found = re.compile(pattern).search(self.text, after)
            if found is not None:
                return found.start()
            assert self.proc.poll() is None, self.text[-3000:]
            time.sleep(0.1)
        raise AssertionError(f"{pattern!r} not seen; the pane ends with:\n{self.text[-3000:]}")

    def type(self, keys: bytes) -> None:
        os.write(self.primary, keys)

    def close(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        self.proc.wait(30)
        self._reader.join(5)
        os.close(self.primary)


def _tool(runtime: Path, *args: str) -> str:
    done = dive(runtime, *args, timeout=60)
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    return done.stdout


def _status_alarm(runtime: Path) -> str:
    """The alarm field at the end of `dive status`'s status line ("" when it ends with the link's field)."""
    line = next(line for line in _tool(runtime, "status").splitlines() if line.startswith("status: "))
    last = line.rsplit(" | ", 1)[-1]
    return "" if last.startswith(("rtt", "link down")) else last


def test_a_tank_day_in_the_run_pane(tmp_path: Path) -> None:
    runtime = tmp_path / "runtime"
    env = {**dive_env(runtime), "TERM": "xterm-256color"}
    env.pop("COLUMNS")  # the terminal's own width
    pane = Pane([*DIVE, "run", "sim://?speed=10&seed=4", "--success-time", "300", "--alarm-depth", "0.9",
                 "--out", str(tmp_path / "rec")], env)
    try:
        # learning: the status line shows the time held of the success time and the target
        at = pane.wait_for(r"LEARNING \| episode \d+ \| [^|]+\| held \d+/300 s \| target 0\.40 m \| depth ")
        _tool(runtime, "mark", "tapped the tank")
        at = pane.wait_for(r"> dive mark: mark 'tapped the tank'", at)
        _tool(runtime, "pause")
        at = pane.wait_for(r"> dive pause: pause: accepted; the agent was (LEARNING|RECOVERING)", at)
        _tool(runtime, "target", "0.6")
        at = pane.wait_for(r"> dive target: target 0\.6 m: accepted; the agent was PAUSED", at)
        pane.wait_for(r"PAUSED \|[^\n]*\| target 0\.60 m \|", at)
        _tool(runtime, "params", "set", "success_time_s", "250")
        at = pane.wait_for(r"> dive params: set success_time_s = 250: accepted; the agent was PAUSED", at)

        # a depth alarm: raised, acknowledged from another pane while it lasts, cleared below its hysteresis
        _tool(runtime, "hover", "1.2")
        at = pane.wait_for(r"> dive hover: hover 1\.2 m: accepted", at)
        at = pane.wait_for(r"ALARM: depth \d\.\d+ m is past the 0\.9 m limit", at)
        pane.wait_for(r"\| ALARM depth", at)
        assert _status_alarm(runtime) == "ALARM depth"  # `dive status` from another pane shows the run's flag
        acked = _tool(runtime, "ack")
        assert "alarms acknowledged by dive ack: depth (active)" in acked, acked
        at = pane.wait_for(r"> alarms acknowledged by dive ack: depth \(active\)", at)
        pane.wait_for(r"\| alarm depth \(acked\)", at)
        assert _status_alarm(runtime) == "alarm depth (acked)"
        _tool(runtime, "hover", "0.3")
        at = pane.wait_for(r"cleared: depth 0\.\d\d m, back above the 0\.9 m limit", at)

        # again, cleared before anybody looked: the flag stays until the key a in the run pane
        _tool(runtime, "hover", "1.2")
        at = pane.wait_for(r"ALARM: depth", at)
        _tool(runtime, "hover", "0.3")
        at = pane.wait_for(r"cleared: depth", at)
        pane.wait_for(r"\| ALARM depth \(cleared\)", at)
        assert _status_alarm(runtime) == "ALARM depth (cleared)"
        pane.type(b"a")
        at = pane.wait_for(r"> alarms acknowledged by the run pane \(key a\): depth \(cleared\)", at)
        assert _status_alarm(runtime) == ""
        assert "no alarm to acknowledge" in _tool(runtime, "ack")  # nothing left: the flag has gone

        _tool(runtime, "start")
        at = pane.wait_for(r"> dive start: start: accepted; the agent was HOVER", at)
        pane.wait_for(r"(RECOVERING|LEARNING) \|", at)
        pane.type(b"\x03")  # Ctrl-C, as the terminal sends it
        end = pane.wait_for(r"stopped by Ctrl-C; the agent was (RECOVERING|LEARNING) at \d\.\d\d m: CMD_STOP "
                            r"accepted, it surfaces \(SURFACING\); the recording is complete", at)
        assert pane.proc.wait(60) == 130
        assert "ALARM" not in re.sub(r"ALARM: [^\n]*", "", pane.text[at:end])  # after the key, no flag came back
    finally:
        pane.close()
