"""`dive mark`: a marker into one running `dive run`'s recording, through its hub, confirmed by the run."""

from __future__ import annotations

import contextlib
import socket
import time

from groundstation.errors import LinkError, LinkTimeout
from groundstation.links.hub import MARKER_CONFIRMATION
from groundstation.links.hub_auth import tool_side
from groundstation.links.runs import RunInfo
from groundstation.links.tcp import parse_host_port
from groundstation.session.hello import ground_hello
from protocol import FrameEncoder, StreamDecoder
from protocol import messages as m

CONFIRMATION = MARKER_CONFIRMATION  # what the hub answers (groundstation/run/hub.py)


def send_marker(run: RunInfo, text: str, timeout_s: float = 3.0) -> None:
    """Send `text` as a marker to the run's hub and wait for its confirmation; LinkError if none comes."""
    host, port = parse_host_port(run.hub)
    encoder, decoder = FrameEncoder(), StreamDecoder()
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as e:
        raise LinkError(f"cannot reach dive run {run.run} at {run.hub} ({e.strerror or e})") from e
    with contextlib.closing(sock):
        tool_side(sock, run.token, f"dive run {run.run} ({run.hub})", timeout_s)
        sock.sendall(encoder.encode(ground_hello(0, 0)).wire
                     + encoder.encode(m.Text(t_us=time.time_ns() // 1000, severity=1, text=text)).wire)
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            sock.settimeout(max(0.01, deadline - time.monotonic()))
            try:
                data = sock.recv(65536)
            except TimeoutError:
                break
            except OSError as e:
                raise LinkError(f"dive run {run.run}: {e.strerror or e}") from e
            if not data:
                break
            for frame in decoder.feed(data):
                if isinstance(frame.message, m.Text) and frame.message.text == CONFIRMATION:
                    return
    raise LinkTimeout(f"dive run {run.run} did not confirm the marker within {timeout_s:g} s")
