"""sim:// links: start the virtual agent (`python -m simulator serve`) as a child process and connect to it.

Every `dive sim` option is a query parameter: sim://?speed=max&seed=3&drop=0.05&disconnect_every=5.
The child lives as long as the link: reconnects go to the same child, close() stops it.
"""

from __future__ import annotations

import subprocess
import tempfile
import threading
from urllib.parse import parse_qsl, urlsplit

from groundstation.errors import LinkError, LinkTimeout
from groundstation.links import Link
from groundstation.links.tcp import TcpLink
from groundstation.simulator_process import child_options, simulator_command

# The Python agent prints its address once imported (seconds; its kernels compile after, answering BUSY meanwhile);
# the C firmware's host build and QEMU's image are made before theirs: a cold `make` is minutes on a loaded machine.
START_TIMEOUT_S = 180.0


def sim_arguments(url: str) -> list[str]:
    """`serve` arguments for a sim:// URL: each query key becomes --key (underscores as dashes)."""
    args = ["serve", "--tcp", "127.0.0.1:0"]
    for key, value in parse_qsl(urlsplit(url).query, keep_blank_values=True):
        if key in ("tcp", "pty"):
            raise LinkError(f"{url}: sim:// chooses its own transport; drop {key!r}")
        args.append("--" + key.replace("_", "-"))
        if value:
            args.append(value)
    return args


class SimLink(Link):
    def __init__(self, url: str) -> None:
        super().__init__(url)
        self.arguments = sim_arguments(url)
        self._child: subprocess.Popen[bytes] | None = None
        self._tcp: TcpLink | None = None
        self.agent_url: str | None = None

    def _start_child(self) -> str:
        stderr = tempfile.TemporaryFile()
        try:
            # Its own session: a Ctrl-C in the terminal or a SIGTERM to dive's process group (timeout, systemd) reaches
            # dive alone, which stops the run as asked and then the child; a child killed first had the run reconnect
            # to a fresh agent and end "another agent answered" (issue 25 L1). PDEATHSIG still ends it with dive.
            child = subprocess.Popen(
                simulator_command(self.arguments), stdout=subprocess.PIPE, stderr=stderr, stdin=subprocess.DEVNULL,
                start_new_session=True, **child_options(),
            )
        except OSError as e:
            raise LinkError(f"{self.url}: cannot start the virtual agent ({e})") from e
        self._child = child
        assert child.stdout is not None
        first: list[bytes] = []
        reader = threading.Thread(target=lambda: first.append(child.stdout.readline()), daemon=True)  # type: ignore[union-attr]
        reader.start()
        reader.join(START_TIMEOUT_S)
        line = first[0].decode(errors="replace").strip() if first else ""
        if not line.startswith("tcp://"):
            self._stop_child()
            stderr.seek(0)
            lines = [x for x in stderr.read().decode(errors="replace").splitlines() if x.strip()]
            why = lines[-1] if lines else (f"no address within {START_TIMEOUT_S:.0f} s" if not first or not line
                                           else repr(line))
            raise LinkError(f"{self.url}: the virtual agent did not start: {why}")
        # Keep draining stdout so the child never blocks on a full pipe.
        threading.Thread(target=lambda: child.stdout.read() if child.stdout else None, daemon=True).start()
        return line

    def _stop_child(self) -> None:
        child, self._child = self._child, None
        if child is None:
            return
        if child.poll() is None:
            child.terminate()
            try:
                child.wait(5.0)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait(5.0)
        if child.stdout is not None:
            child.stdout.close()

    def _connect(self) -> None:
        if self._child is None or self._child.poll() is not None:
            self.agent_url = self._start_child()
        assert self.agent_url is not None
        self._tcp = TcpLink(self.agent_url)
        try:
            self._tcp.open()
        except LinkTimeout:
            raise
        except LinkError as e:
            raise LinkError(f"{self.url}: {e}") from e

    def _disconnect(self) -> None:
        tcp, self._tcp = self._tcp, None
        if tcp is not None:
            tcp.close()

    def _release(self) -> None:
        self._stop_child()

    def _live(self) -> TcpLink:
        if self._tcp is None:
            raise LinkError(f"{self.url}: not connected")
        return self._tcp

    def _read(self, timeout_s: float) -> bytes:
        return self._live()._read(timeout_s)

    def _write(self, data: bytes) -> None:
        self._live()._write(data)
