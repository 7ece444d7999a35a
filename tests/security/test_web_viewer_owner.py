"""Rerun's web viewer answers the run's owner only (issue 38): another local user gets neither the page nor the data
stream at the ports the run printed, and cannot use the run's own socket to the servers; the owner gets both. Where
the machine gives no private network, `--viewer web` is refused in one line instead of served to everyone.

The first test needs root (to run the intruder as `nobody`) and is skipped with one line elsewhere.
"""

from __future__ import annotations

import json
import os
import shutil
import socket
import subprocess
import sys
import time
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import rerun as rr

from groundstation.view.native_viewer import NativeViewer, start_native_viewer
from groundstation.view.web_server import PrivateRerun, WebViewerServer
from tests.groundstation.rrd_readback import rows_per_entity
from tests.security.attack import as_another_user
from tests.waiting import wait_for

SYSTEM_PYTHON = shutil.which("python3", path="/usr/bin:/bin")  # the intruder's: outside root's home, stdlib only
INTRUDER = Path(__file__).with_name("web_intruder.py")
XVFB = shutil.which("Xvfb")
DIVE = str(Path(sys.executable).with_name("dive"))
ENTITY = "/owner/value"
ROWS = 50


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port: int = s.getsockname()[1]
        return port


def _ask(server: PrivateRerun, **user: object) -> dict[str, dict[str, object] | str]:
    """The intruder's requests at the printed ports (as the owner, or as another user with `user`)."""
    web_port, grpc_port = server.ports.get(b"w", server.ports[b"g"]), server.ports[b"g"]
    done = subprocess.run([SYSTEM_PYTHON or sys.executable, str(INTRUDER), str(web_port), str(grpc_port),
                           str(server.bridge_socket)], cwd="/", env={"PATH": os.environ["PATH"]},
                          capture_output=True, text=True, timeout=60, **user)  # type: ignore[call-overload]
    assert done.returncode == 0, done.stderr
    report: dict[str, dict[str, object] | str] = json.loads(done.stdout)
    return report


def _read_as_a_viewer(server: WebViewerServer, out: Path) -> int:
    """The rows of ENTITY a Rerun viewer connected to the printed data URL receives (the rerun CLI as the client,
    saving what it is sent; read back with Rerun's own reader)."""
    viewer = subprocess.Popen([str(Path(sys.executable).with_name("rerun")), server.uri, "--save", str(out),
                               "--port", str(_free_port())], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    rows = 0
    try:
        deadline = time.monotonic() + 30.0
        while rows < ROWS and time.monotonic() < deadline:
            time.sleep(0.5)
            if out.exists() and out.stat().st_size:
                copy = out.with_suffix(".copy.rrd")
                shutil.copyfile(out, copy)  # the file is still being written: read a copy
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")  # a stream still being written has no footer: Rerun says so
                        rows = rows_per_entity(copy)[ENTITY]
                except Exception:  # noqa: BLE001 a copy cut mid-message: try the next one
                    rows = 0
    finally:
        viewer.terminate()
        viewer.wait(10)
    return rows


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to act as another local user (nobody)")
@pytest.mark.skipif(SYSTEM_PYTHON is None, reason="no system python3 for the other user to run")
def test_another_user_gets_nothing_from_the_web_viewer_and_the_owner_gets_the_page_and_the_data(
        tmp_path: Path) -> None:
    server = WebViewerServer.start(_free_port(), _free_port(), "64MiB")
    try:
        rec = rr.RecordingStream("owner-test")
        rec.set_sinks(rr.GrpcSink(server.uri))  # the run's own stream goes in through the same door
        for i in range(ROWS):
            rec.set_time("step", sequence=i)
            rec.log(ENTITY, rr.Scalars([float(i)]))
        rec.flush()
        other = _ask(server, **as_another_user())
        owner = _ask(server)
        rows = _read_as_a_viewer(server, tmp_path / "owner.rrd")
    finally:
        server.close()
    for request in ("page", "grpc_web", "grpc_h2"):  # the page, the browser's data, the SDK's data
        answer = other[request]
        assert isinstance(answer, dict)
        assert answer["status"] in ("HTTP/1.1 403 Forbidden", "") and answer["body"] == 0, (request, answer)
    assert other["bridge"] == "PermissionError", other  # the run's socket to the private servers: not theirs
    page, data = owner["page"], owner["grpc_web"]
    assert isinstance(page, dict) and isinstance(data, dict)
    assert page["status"] == "HTTP/1.1 200 OK" and int(str(page["body"])) > 1000, page
    assert data["status"] == "HTTP/1.1 200 OK" and int(str(data["body"])) > 0, data  # the recording, to a browser
    assert rows == ROWS  # and every row of it to a viewer


def test_where_no_private_network_is_allowed_the_web_viewer_is_refused_in_one_line() -> None:
    """A machine that gives no unprivileged user namespace (Ubuntu's AppArmor restriction, macOS) is played by a
    user namespace whose limit of further namespaces is 0, where the kernel refuses unshare as it does there."""
    no_namespaces = ["unshare", "--user", "--map-root-user", "sh", "-c",
                     'echo 0 > /proc/sys/user/max_user_namespaces && exec "$@"', "sh"]
    if shutil.which("unshare") is None or subprocess.run([*no_namespaces[:3], "true"]).returncode != 0:
        no_namespaces = []  # this machine refuses them already: dive meets the same refusal as it is
    done = subprocess.run([*no_namespaces, DIVE, "view", "tcp://127.0.0.1:9", "--viewer", "web",
                           "--web-port", str(_free_port()), "--grpc-port", str(_free_port())],
                          capture_output=True, text=True, timeout=60, env={**os.environ, "DISPLAY": ""})
    assert done.returncode == 2, (done.returncode, done.stdout, done.stderr)
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dive: --viewer web cannot keep"), lines
    assert "every local user" in lines[0] and "--foxglove" in lines[0] and "--rrd" in lines[0], lines


@contextmanager
def _x_display() -> Iterator[str]:
    """A virtual X display of our own (Xvfb) on a free number, as a desktop's: reached by a unix socket."""
    number = next(n for n in range(140, 200) if not Path(f"/tmp/.X11-unix/X{n}").exists()
                  and not Path(f"/tmp/.X{n}-lock").exists())
    server = subprocess.Popen([XVFB or "Xvfb", f":{number}", "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert wait_for(lambda: Path(f"/tmp/.X11-unix/X{number}").exists(), 20), "Xvfb did not start"
        yield f":{number}"
    finally:
        server.terminate()
        server.wait(10)


def _windows(display: str) -> int:
    tree = subprocess.run(["xwininfo", "-root", "-tree"], capture_output=True, text=True, timeout=20,
                          env={**os.environ, "DISPLAY": display}).stdout
    return tree.count('"Rerun"')


@pytest.mark.skipif(os.geteuid() != 0, reason="needs root to act as another local user (nobody)")
@pytest.mark.skipif(SYSTEM_PYTHON is None, reason="no system python3 for the other user to run")
@pytest.mark.skipif(XVFB is None or shutil.which("xwininfo") is None, reason="no Xvfb and xwininfo for a display")
def test_the_native_viewers_port_is_the_owners_and_a_second_run_reuses_its_window(
        monkeypatch: pytest.MonkeyPatch) -> None:
    """`--viewer spawn`: rr.spawn's viewer listened on 0.0.0.0:9876, where anyone (on the network too) could read
    the run and command the viewer (open a URL, quit: its gRPC API). Now another user gets 403 at its port, the
    owner's data arrives, and a second run streams into the same window as rr.spawn's reuse did."""
    with _x_display() as display:
        monkeypatch.setenv("DISPLAY", display)
        monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
        port = _free_port()
        first = start_native_viewer(port, "256MiB", "64MiB")
        assert isinstance(first, NativeViewer)  # private: this machine gives user namespaces (the test above)
        try:
            rec = rr.RecordingStream("owner-test")
            rec.set_sinks(rr.GrpcSink(first.uri))
            for i in range(ROWS):
                rec.set_time("step", sequence=i)
                rec.log(ENTITY, rr.Scalars([float(i)]))
            rec.flush()
            rec.disconnect()
            other = _ask(first, **as_another_user())
            owner = _ask(first)
            first.close()  # the run ends: its door closes, its window stays
            second = start_native_viewer(port, "256MiB", "64MiB")
            second.close()
            windows = _windows(display)
        finally:
            first.stop()
    for request in ("grpc_web", "grpc_h2"):
        answer = other[request]
        assert isinstance(answer, dict)
        assert answer["status"] in ("HTTP/1.1 403 Forbidden", "") and answer["body"] == 0, (request, answer)
    assert other["bridge"] == "PermissionError", other
    data = owner["grpc_web"]
    assert isinstance(data, dict) and data["status"] == "HTTP/1.1 200 OK" and int(str(data["body"])) > 0, data
    assert not isinstance(second, NativeViewer) and windows == 1  # the same window, not a second one


def test_a_native_viewer_on_loopback_says_every_local_user_can_read_it(capfd: pytest.CaptureFixture[str]) -> None:
    """Where the viewer cannot have a private network (or the display is over TCP), its port is on 127.0.0.1: the
    tools say so in one line beside the viewer's address, rather than let the owner think it is theirs alone."""
    from groundstation.cli.live_views import say_where
    from groundstation.view.native_viewer import LoopbackNativeViewer
    from groundstation.view.rerun_sink import RerunView

    with socket.socket() as held:  # a viewer already listening there: rr.spawn's reuse, nothing started
        held.bind(("127.0.0.1", 0))
        held.listen()
        port = held.getsockname()[1]
        viewer = LoopbackNativeViewer(port, "1GB", "1GB")
        view = RerunView(rr.RecordingStream("test-notice"), viewer)
        say_where(view)
    err = capfd.readouterr().err.splitlines()
    assert err == [f"note: the native viewer's data port 127.0.0.1:{port} is readable by every local user here (no "
                   "private network for it on this machine, or the display is over TCP): use --foxglove or --rrd "
                   "FILE on a shared machine"], err
