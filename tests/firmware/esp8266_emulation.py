"""The ESP8266 bridge sketch built against the ESP8266 Arduino core's own host emulation (its tests/host: the sketch
compiled for Linux, WiFiServer/WiFiClient on real sockets, Serial on stdin/stdout), and run with its Serial on an
agent's pseudo-terminal. The core is copied once into a cache keyed by the vendor commit and the shim (its build
takes minutes); each test session builds the sketch from the repository into its own folder."""

from __future__ import annotations

import fcntl
import hashlib
import os
import re
import shutil
import socket
import subprocess
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest

from tests.firmware.core_build import FIRMWARE, ROOT

VENDOR = ROOT.parent / "shared" / "vendor" / "esp8266-arduino"  # CI keeps shared/ beside the clone
SKETCH = FIRMWARE / "esp8266" / "esp8266_bridge" / "esp8266_bridge.ino"
HOST_DIR = Path(__file__).resolve().parent / "esp8266_host"  # bridge_config.h, the shim and the patch
SHIM = HOST_DIR / "wifi_server_shim.cpp"
# The emulation's main loop reads stdin a byte at a time and took a 0x00 byte for "nothing read" and dropped it; the
# agent ends every frame with 0x00, so now and then two frames merged and both were lost. The patch keeps the byte.
PATCH = HOST_DIR / "main_loop_nul_byte.patch"
TCP_PORT = 23  # the sketch's port; the emulation adds its port shifter (-s) to ports below 1024
CACHE = Path(os.environ.get("DIVE_ESP8266_CACHE", Path.home() / ".cache" / "diving-agent" / "esp8266-host"))


def vendor_commit() -> str:
    """The ESP8266 core's commit as shared/vendor/README.md names it, or skip: no core beside the repository."""
    for tool in ("make", "g++", "gcc", "patch"):
        if shutil.which(tool) is None:
            pytest.skip(f"{tool} not on PATH: the ESP8266 bridge emulation test is skipped")
    readme = VENDOR.parent / "README.md"
    found = re.search(r"esp8266/Arduino ([0-9a-f]{7,40})", readme.read_text()) if readme.exists() else None
    if not (VENDOR / "tests" / "host" / "Makefile").exists() or found is None:
        pytest.skip(f"no ESP8266 Arduino core at {VENDOR}: the ESP8266 bridge emulation test is skipped")
    return found.group(1)


@contextmanager
def _locked(path: Path) -> Iterator[None]:
    """Holds an exclusive lock on path: other xdist workers and other checkouts on this machine share the cache."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def _make(host: Path, shim: Path, target: str, cflags: list[str]) -> subprocess.CompletedProcess[str]:
    """The emulation's own Makefile (tests/host), native 64-bit (FORCE32=0: no multilib needed), with the shim,
    without its optional libraries (mDNS, web server, OTA, HTTP client...: the bridge uses none; a fifth less to
    build)."""
    return subprocess.run(["make", "-j2", "-C", str(host), "FORCE32=0", "OPT_ARDUINO_LIBS=", f"USERCXXSOURCES={shim}",
                           f"USERCFLAGS={' '.join(cflags)}", target],
                          capture_output=True, text=True, timeout=1200, check=False)


def build_bridge(session_dir: Path, access_point: bool) -> Path:
    """The bridge sketch, copied unchanged from the repository, compiled with -Wall -Wextra -Werror against the
    emulation and linked with its core: the executable's path. Once per session and mode."""
    ours = hashlib.sha256(SHIM.read_bytes() + PATCH.read_bytes()).hexdigest()[:12]
    cache = CACHE / f"{vendor_commit()}-{ours}"
    host = cache / "esp8266-arduino" / "tests" / "host"
    shim = cache / SHIM.name
    mode = "access-point" if access_point else "station"
    sketch = session_dir / mode / "esp8266_bridge" / SKETCH.name
    binary = session_dir / mode / "bridge"
    with _locked(CACHE / "lock"):
        if binary.exists():  # another worker of this session built it
            return binary
        if not host.exists():  # the emulation builds beside its sources: a copy of the tree, renamed when whole
            partial = cache / "copying"
            shutil.rmtree(partial, ignore_errors=True)
            shutil.copytree(VENDOR, partial)
            patched = subprocess.run(["patch", "-p1", "--forward", "-i", str(PATCH)], cwd=partial,
                                     capture_output=True, text=True, check=False)
            assert patched.returncode == 0, f"{PATCH.name} does not apply: {patched.stdout}{patched.stderr}"
            partial.rename(cache / "esp8266-arduino")
        if not shim.exists():  # inside the cache, untouched after, so make never rebuilds fullcore.a for this key
            shutil.copyfile(SHIM, shim)
        core = _make(host, shim, str(host / "bin" / "fullcore.a"), [])  # the vendor's warnings are not ours
        assert core.returncode == 0, core.stdout[-3000:] + core.stderr[-3000:]
        sketch.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(SKETCH, sketch)
        flags = ["-Wall", "-Wextra", "-Werror", f"-I{HOST_DIR}", f"-I{FIRMWARE / 'generated'}"]
        if access_point:
            flags.append("-DBRIDGE_AP_MODE=1")
        done = _make(host, shim, str(sketch.with_suffix("")), flags)
        assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
        built = host / "bin" / str(sketch.with_suffix("")).lstrip("/")  # the Makefile's $(BINDIR)/$(abspath ...)
        shutil.move(built, binary)
        shutil.rmtree(host / "bin" / str(session_dir).lstrip("/"), ignore_errors=True)  # this session's objects
        return binary


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _listening(port: int) -> bool:
    """True once a socket listens on port (read from /proc: a probe connection would be a ground to the bridge)."""
    for line in Path("/proc/net/tcp").read_text().splitlines()[1:]:
        parts = line.split()
        if parts[1].endswith(f":{port:04X}") and parts[3] == "0A":
            return True
    return False


@contextmanager
def bridge_on(binary: Path, device: str, log: Path) -> Iterator[str]:
    """The bridge running with its Serial (the emulation's stdin/stdout) on the agent's pseudo-terminal: yields
    tcp://127.0.0.1:PORT. `-f`: without it the emulation takes one UART byte per 1 ms loop (1 kB/s, a tenth of the
    real 115200 baud); `-s`: its port shifter, so the sketch's port 23 lands on a free port; `-S 0 -L 0`: no SPIFFS
    or LittleFS image files beside the executable."""
    port = _free_port()
    serial = os.open(device, os.O_RDWR | os.O_NOCTTY)
    with open(log, "w") as stderr:
        bridge = subprocess.Popen([str(binary), "-f", "-S", "0", "-L", "0", "-s", str(port - TCP_PORT)],
                                  stdin=serial, stdout=serial, stderr=stderr)
    os.close(serial)
    try:
        deadline = time.monotonic() + 30
        while not _listening(port):
            assert bridge.poll() is None, f"the bridge stopped: {log.read_text()}"
            assert time.monotonic() < deadline, f"the bridge is not listening on {port}: {log.read_text()}"
            time.sleep(0.05)
        yield f"tcp://127.0.0.1:{port}"
        assert bridge.poll() is None, f"the bridge stopped: {log.read_text()}"
    finally:
        bridge.terminate()  # SIGTERM ends the emulation's loop; it puts the terminal back
        try:
            bridge.wait(10)
        except subprocess.TimeoutExpired:
            bridge.kill()
            bridge.wait(10)
