"""The C firmware's host build (firmware/boards/host) as an OnboardAgent: `dive sim --firmware c`.

The C on-board program does what the Teensy does (depth from pressure, observer, modes, recovery, learner,
the whole protocol); Python is only the world around it: the plant and the pressure sensor of simulator/,
the battery, the clocks and the link bytes. They meet in one shared I/O block (host_io_t): Python fills
the inputs, calls the library once per control step (or per batch of received bytes), then drains what
the firmware wrote. No Python callback runs inside the C code.

The library is built on demand with `make -C firmware host` into a cache directory keyed by a hash of
the firmware sources, so an edited source is rebuilt and two checkouts never share a stale build.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

import numpy as np

from simulator.agent.hardware import SimulatedHardware
from simulator.agent.onboard import Write
from simulator.errors import SimulatorError
from simulator.parameters import PlantParams

FIRMWARE_DIR = Path(__file__).resolve().parents[2] / "firmware"
LIBRARY_NAME = "libdiveagent.so"
LIBRARY_ENV = "DIVE_FIRMWARE_LIB"  # a prebuilt library to load instead of building one
CACHE_ENV = "DIVE_FIRMWARE_CACHE"  # where built libraries are kept (default ~/.cache/diving-agent)
HOST_IO_VERSION = 1
HOST_RX_BYTES = 4096
HOST_TX_BYTES = 262144
HOST_NV_BYTES = 64
HOST_LOG_MAX_BYTES = 512 * 1024
HOST_COUNTERS = 5
_SOURCE_DIRS = ("src", "include", "generated", "boards/host")


class FirmwareBuildError(SimulatorError):
    """The host library could not be found or built (no compiler, no firmware sources)."""


class HostIo(ctypes.Structure):
    """host_io_t of firmware/boards/host/host_io.h, field for field (the C side reports its size to check)."""

    _fields_ = [
        ("version", ctypes.c_uint32), ("size_bytes", ctypes.c_uint32),
        ("time_us", ctypes.c_uint64), ("link_time_us", ctypes.c_uint64),
        ("pressure_pa", ctypes.c_float), ("stepper_deg", ctypes.c_float), ("battery_v", ctypes.c_float),
        ("rx_len", ctypes.c_uint32), ("rx_pos", ctypes.c_uint32),
        ("stepper_cmd_deg", ctypes.c_float), ("tx_len", ctypes.c_uint32), ("tx_dropped", ctypes.c_uint32),
        ("pressure_reads", ctypes.c_uint32), ("nv_writes", ctypes.c_uint32),
        ("log_capacity_bytes", ctypes.c_uint32), ("entropy_state", ctypes.c_uint32), ("nv_len", ctypes.c_uint32),
        ("nv", ctypes.c_uint8 * HOST_NV_BYTES), ("rx", ctypes.c_uint8 * HOST_RX_BYTES),
        ("tx", ctypes.c_uint8 * HOST_TX_BYTES),
    ]


def _source_hash() -> str:
    digest = hashlib.sha256()
    files = [FIRMWARE_DIR / "Makefile"]
    for folder in _SOURCE_DIRS:
        files += sorted(p for p in (FIRMWARE_DIR / folder).glob("*") if p.suffix in (".c", ".h"))
    for path in files:
        digest.update(path.relative_to(FIRMWARE_DIR).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def _cache_dir() -> Path:
    configured = os.environ.get(CACHE_ENV)
    if configured:
        return Path(configured)
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "diving-agent" / "firmware-host"


def library_path() -> Path:
    """The host library for the current sources: $DIVE_FIRMWARE_LIB, or a cached build (built if missing)."""
    configured = os.environ.get(LIBRARY_ENV)
    if configured:
        path = Path(configured)
        if not path.is_file():
            raise FirmwareBuildError(f"{LIBRARY_ENV}={configured}: no such file")
        return path
    if not (FIRMWARE_DIR / "Makefile").is_file():
        raise FirmwareBuildError(f"the C firmware sources are not installed ({FIRMWARE_DIR} is missing)")
    target = _cache_dir() / _source_hash() / LIBRARY_NAME
    if not target.is_file():
        build_library(target)
    return target


def build_library(target: Path) -> None:
    """`make -C firmware host` into a private folder, then moved into place (concurrent builds do not clash)."""
    for tool in ("make", os.environ.get("CC", "cc")):
        if shutil.which(tool) is None:
            raise FirmwareBuildError(f"cannot build the C firmware: {tool!r} not found (install make and a C compiler)")
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent) as scratch:
        built = Path(scratch) / LIBRARY_NAME
        command = ["make", "-s", "-C", str(FIRMWARE_DIR), "host", f"BUILD={scratch}", f"HOST_LIB={built}",
                   f"HOST_CC={os.environ.get('CC', 'cc')}"]
        result = subprocess.run(command, capture_output=True, text=True, check=False)
        if result.returncode != 0 or not built.is_file():
            lines = [line for line in (result.stderr or result.stdout).splitlines() if line.strip()]
            raise FirmwareBuildError(f"cannot build the C firmware: {lines[0] if lines else 'make failed'}")
        os.replace(built, target)


def load_library(path: Path | None = None) -> ctypes.CDLL:
    """The loaded host library with its entry points typed."""
    path = path or library_path()
    try:
        lib = ctypes.CDLL(str(path))
    except OSError as e:
        raise FirmwareBuildError(f"cannot load the C firmware {path}: {e}") from e
    lib.host_io.restype = ctypes.POINTER(HostIo)
    lib.host_io_size.restype = ctypes.c_uint32
    lib.host_init.argtypes = [ctypes.c_uint32, ctypes.c_char_p]
    lib.host_step.restype = ctypes.c_uint32
    lib.host_next_seq.restype = ctypes.c_uint16
    if lib.host_io_size() != ctypes.sizeof(HostIo):
        raise FirmwareBuildError(f"{path}: host_io_t is {lib.host_io_size()} bytes, this loader expects "
                                 f"{ctypes.sizeof(HostIo)} (stale build?)")
    return lib


def _read_nv(path: Path) -> bytes:
    try:
        return path.read_bytes()[:HOST_NV_BYTES]
    except FileNotFoundError:
        return b""
    except OSError as e:
        raise FirmwareBuildError(f"cannot read the agent's state file {path}: {e.strerror or e}") from e


def _write_nv(path: Path, data: bytes) -> None:
    """As an EEPROM write: the file is replaced whole, never left half written."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        scratch = path.with_name(path.name + ".tmp")
        scratch.write_bytes(data)
        os.replace(scratch, path)
    except OSError as e:
        raise FirmwareBuildError(f"cannot write the agent's state file {path}: {e.strerror or e}") from e


class FirmwareAgent:
    """The C on-board program against the Python plant and sensor, one library per process (static state)."""

    def __init__(self, plant: PlantParams, rng: np.random.Generator, write: Write, node_id: int, key: bytes | None,
                 seed: int, wall_link_clock: bool = True, nv_file: Path | None = None, nv: bytes = b"",
                 log_capacity_bytes: int = HOST_LOG_MAX_BYTES) -> None:
        """The firmware has its own parameter defaults (protocol/parameters.py): learner and mission presets of
        the Python agent do not apply to it (a ground station sets parameters with PARAM_SET, as on the real agent).

        wall_link_clock: the link's clock is wall time (an agent faster than real time), else agent time.
        nv_file: where the non-volatile area (the signing mark) survives a restart; `nv` is its content otherwise.
        log_capacity_bytes: the on-board log's size (the agent's two EEPROMs hold 512 KiB; tests use less).
        """
        if not 0 < log_capacity_bytes <= HOST_LOG_MAX_BYTES:
            raise FirmwareBuildError(f"log capacity {log_capacity_bytes} B outside 1..{HOST_LOG_MAX_BYTES}")
        self._write = write
        self._wall_link_clock = wall_link_clock
        self._nv_file = nv_file
        if nv_file is not None:
            nv = _read_nv(nv_file)
        self.hw = SimulatedHardware(plant, rng)
        self._lib = load_library()
        self._io = self._lib.host_io().contents
        self._io.log_capacity_bytes = log_capacity_bytes
        self._io.entropy_state = (seed & 0xFFFFFFFF) or 1
        # The non-volatile area (the signing mark) as a fresh board has it, or as given; the library is one per
        # process, so an earlier agent's area must not leak into this one.
        nv = nv[:HOST_NV_BYTES]
        ctypes.memmove(ctypes.addressof(self._io.nv), nv, len(nv))
        self._io.nv_len = len(nv)
        self._wall0 = time.monotonic()
        self._fill_inputs()
        self._lib.host_init(node_id & 0xFFFFFFFF, key)
        self._nv_writes = self._io.nv_writes
        self._drain()

    @property
    def t_us(self) -> int:
        return self.hw.t_us

    @property
    def next_seq(self) -> int:
        return int(self._lib.host_next_seq())

    @property
    def true_depth_m(self) -> float:
        return self.hw.true_depth_m

    def _link_time_us(self) -> int:
        # Link silence, HELLO repeats and signature ages run on the link's real clock (SPEC s. 4, time base).
        return int((time.monotonic() - self._wall0) * 1e6) if self._wall_link_clock else self.hw.t_us

    def _fill_inputs(self) -> None:
        io, hw = self._io, self.hw
        io.time_us = hw.t_us
        io.link_time_us = self._link_time_us()
        io.pressure_pa = hw.read_pressure_pa()
        io.stepper_deg = hw.actuator_deg
        io.battery_v = hw.battery_v

    def _drain(self) -> None:
        io = self._io
        n = io.tx_len
        if n:
            data = ctypes.string_at(ctypes.addressof(io.tx), n)
            io.tx_len = 0
            start = 0
            while start < n:  # one frame per write: the server's fault injection works frame by frame
                end = data.index(0, start) + 1
                self._write(data[start:end])
                start = end
        if self._nv_file is not None and io.nv_writes != self._nv_writes:
            self._nv_writes = io.nv_writes
            _write_nv(self._nv_file, ctypes.string_at(ctypes.addressof(io.nv), io.nv_len))

    def step(self) -> None:
        self._fill_inputs()
        self._lib.host_poll()  # as the board's loop: link first (pending replies go out), then the step
        period_us = int(self._lib.host_step())
        self.hw.set_actuator_cmd_deg(float(self._io.stepper_cmd_deg))
        self._drain()
        self.hw.advance(period_us / 1e6)

    def receive(self, data: bytes) -> None:
        io = self._io
        view = memoryview(data)
        while view:
            chunk = view[:HOST_RX_BYTES]
            view = view[HOST_RX_BYTES:]
            ctypes.memmove(ctypes.addressof(io.rx), bytes(chunk), len(chunk))
            io.rx_pos, io.rx_len = 0, len(chunk)
            io.link_time_us = self._link_time_us()
            self._lib.host_poll()
            self._drain()

    work_after_ack = False  # the firmware's learner restart is a memset: it runs before the ACK is built

    def finish_command(self) -> None:
        pass

    def service(self) -> None:
        self._io.link_time_us = self._link_time_us()
        self._lib.host_poll()  # pending replies, the HELLO repeat until the ground is heard
        self._drain()

    def link_up(self) -> None:
        self._lib.host_link_up()
        self._drain()

    def link_down(self) -> None:
        """Nothing to do: the firmware notices a new link at the next link_up (as a serial agent never knows)."""

    def counters(self) -> dict[str, int]:
        values = (ctypes.c_uint32 * HOST_COUNTERS)()
        self._lib.host_counters(values)
        names = ("next_sample", "signing_rejects", "rx_lost", "rx_rejects", "rx_frames")
        return dict(zip(names, (int(v) for v in values), strict=True))
